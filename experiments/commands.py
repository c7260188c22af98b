"""Registry of the subcommands implemented outside ``experiments.cli`` (imported for side effects).

Add one import line per module that registers commands on ``experiments.cli.app``.
"""
