"""``python -m experiments.cli``: the ``coobs`` command line."""

from experiments.cli import main

main()
