"""``python -m coobs``: the ``coobs`` command line."""

from coobs.cli import app

app(prog_name="coobs")
