"""Project-wide test settings.

Hypothesis runs derandomised (the same examples on every run, like every other fixed-seed test of
the project) and without its per-example deadline, which a loaded 2-core CI machine or a first-call
compile (Numba, Open3D) would otherwise turn into spurious failures.
"""

from hypothesis import settings

settings.register_profile("coobs", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("coobs")
