"""Keep freed image buffers in the process instead of handing them back to the kernel (glibc only).

A rendered camera-frame allocates and frees buffers of megabytes: the region-of-interest arrays of
the renderer, the sensor's image, SIFT's Gaussian and difference-of-Gaussian pyramids over the
image upsampled twice (about 7 MB per level for a 800 × 550 px region).  With glibc's default
``malloc`` settings many of them are ``mmap``-ed and ``munmap``-ed, or trimmed off the top of the
heap, every frame, and every page of the next frame's buffers is faulted in and zeroed by the kernel
again.  On the 40 m scene of ``coobs bench --only rendered`` that system time was about a third of a
camera-frame's CPU (``docs/vision.md``, "Where a rendered camera-frame's time goes").

:func:`retain_freed_memory` sets two ``mallopt`` parameters so that blocks up to
``mmap_threshold_bytes`` come from the heap and up to ``trim_threshold_bytes`` of free heap stay
mapped.  It changes how memory is reused, never what is computed.  The rendered observer
(:class:`closed_loop.observers.RenderedObserver`) and ``coobs calibrate`` call it; call it yourself
when you render many frames from a notebook.  Elsewhere than glibc (macOS, musl) it does nothing,
and with the environment variable ``COOBS_MALLOC_DEFAULTS=1`` it leaves glibc's defaults (to compare).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

__all__ = ["MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES", "retain_freed_memory"]

_M_TRIM_THRESHOLD = -1         # mallopt parameter numbers of glibc's <malloc.h>
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024    # glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit systems)
TRIM_THRESHOLD_BYTES = 256 * 1024 * 1024


def _libc_mallopt():
    """glibc's ``mallopt``, or None where the C library is not glibc."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.gnu_get_libc_version     # only glibc has it   # noqa: B018
        fn = libc.mallopt
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_int]
    fn.restype = ctypes.c_int
    return fn


def retain_freed_memory(*, mmap_threshold_bytes: int = MMAP_THRESHOLD_BYTES,
                        trim_threshold_bytes: int = TRIM_THRESHOLD_BYTES) -> bool:
    """Let this process keep and reuse its freed buffers (glibc ``mallopt``); True when it was set.

    Parameters
    ----------
    mmap_threshold_bytes : int
        Blocks from this size up are ``mmap``-ed (and unmapped when freed); in (0, 32 MiB].
    trim_threshold_bytes : int
        Free memory at the top of the heap beyond this is handed back to the kernel; > 0.

    Returns
    -------
    bool
        False where the C library is not glibc or ``COOBS_MALLOC_DEFAULTS`` is set to 1 (nothing is
        changed then).
    """
    if not 0 < int(mmap_threshold_bytes) <= MMAP_THRESHOLD_BYTES:
        raise ValueError(f"mmap_threshold_bytes must be in (0, {MMAP_THRESHOLD_BYTES}], got {mmap_threshold_bytes!r}")
    if not 0 < int(trim_threshold_bytes) < 2 ** 31:
        raise ValueError(f"trim_threshold_bytes must be in (0, 2**31), got {trim_threshold_bytes!r}")
    mallopt = _libc_mallopt()
    if mallopt is None or os.environ.get("COOBS_MALLOC_DEFAULTS", "") == "1":
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, int(mmap_threshold_bytes))
                and mallopt(_M_TRIM_THRESHOLD, int(trim_threshold_bytes)))
