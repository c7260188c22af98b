"""The ``progress`` argument of :func:`coobs.run` and :func:`coobs.sweep`: a bar, nothing, or a callback."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

__all__ = ["ProgressLike", "progress_callback"]

#: ``True`` a progress bar (tqdm: text in a terminal, a widget in a notebook), ``False``/``None``
#: nothing, or a callable ``progress(done, total)``
ProgressLike = bool | Callable[[int, int], None] | None


def _tqdm_class() -> Any:
    from tqdm import TqdmWarning

    with warnings.catch_warnings():
        # without ipywidgets, tqdm.auto warns once and falls back to the text bar: the text bar is fine
        warnings.simplefilter("ignore", TqdmWarning)
        from tqdm.auto import tqdm
    return tqdm


def progress_callback(progress: ProgressLike, *, desc: str, unit: str
                      ) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """``(update(done, total) or None, close())`` for a ``progress`` argument.

    Raises
    ------
    TypeError
        ``progress`` is neither a bool, ``None`` nor a callable.
    """
    if progress is None or progress is False:
        return None, lambda: None
    if progress is True:
        bar = None

        def update(done: int, total: int) -> None:
            nonlocal bar
            if bar is None:
                bar = _tqdm_class()(total=total, desc=desc, unit=unit, leave=True)
            bar.total = total
            bar.n = done
            bar.refresh()

        def close() -> None:
            if bar is not None:
                bar.close()

        return update, close
    if callable(progress):
        return progress, lambda: None
    raise TypeError(f"progress: must be True, False or a callable progress(done, total), "
                    f"not {type(progress).__name__}")
