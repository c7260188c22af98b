"""Registry of the subcommands implemented outside ``experiments.cli`` (imported for side effects).

Add one import line per module that registers commands on ``experiments.cli.app``.
"""

from experiments import filter_study as _filter_study  # noqa: F401  (filter-study)
from experiments import scenarios as _scenarios  # noqa: F401  (run, plot)
from experiments import sweep as _sweep  # noqa: F401  (sweep)
from experiments import tumble as _tumble  # noqa: F401  (tumble)
