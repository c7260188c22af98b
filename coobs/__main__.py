"""``python -m coobs``: the ``coobs`` command line."""

from experiments.cli import app

app(prog_name="coobs")
