"""One BLAS thread for the small-inner-dimension products of the geometric modes.

The projections of :mod:`vision.geometric` multiply ``(3, 3)`` rotations by ``(3, N)`` feature
coordinates: OpenBLAS splits such products over its threads once N is large, and the threads then
spin while waiting for the next call: about a third of the CPU of the calibrated mode's close-range
Experiment A cells (four cells of ``coobs bench --only calibrated``'s subset, 30 and 100 m, timed
apart: 14.1 → 9.6 CPU s with ``OPENBLAS_NUM_THREADS=1``, the same observations bit for bit: each
column is computed by the same kernel whatever the thread).  :func:`one_blas_thread` holds OpenBLAS at one thread for a block; where
numpy's BLAS is not an OpenBLAS found here it does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
from collections.abc import Iterator
from pathlib import Path

__all__ = ["one_blas_thread"]


@functools.lru_cache(maxsize=1)
def _openblas() -> tuple | None:
    """``(get, set)`` of the thread count of the OpenBLAS that numpy ships with, or None."""
    import numpy as np

    libs = Path(np.__file__).resolve().parent.parent / "numpy.libs"
    for path in sorted(libs.glob("lib*openblas*.so*")) if libs.is_dir() else []:
        try:
            lib = ctypes.CDLL(str(path))
        except OSError:
            continue
        for get_name, set_name in (("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                                   ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
                                   ("openblas_get_num_threads", "openblas_set_num_threads")):
            get, put = getattr(lib, get_name, None), getattr(lib, set_name, None)
            if get is not None and put is not None:
                get.restype = ctypes.c_int
                put.argtypes = [ctypes.c_int]
                return get, put
    return None


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with one OpenBLAS thread (the previous count restored after it)."""
    lib = _openblas()
    if lib is None:
        yield
        return
    get, put = lib
    before = int(get())
    if before != 1:
        put(1)
    try:
        yield
    finally:
        if before != 1:
            put(before)
