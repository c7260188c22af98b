"""The consoles of the ``coobs`` commands, their one-line error exit, and the progress bar."""

from __future__ import annotations

from collections.abc import Callable

import typer
from rich.console import Console

__all__ = ["console", "err_console", "fail", "progress_bar", "MAX_ERROR_CHARS"]

console = Console()
err_console = Console(stderr=True)


#: longest error line printed, characters (after ``error: ``)
MAX_ERROR_CHARS = 300


def fail(message: str) -> typer.Exit:
    """Print a one-line error (white space runs joined, cut to :data:`MAX_ERROR_CHARS`) and return the exit
    (code 2) to raise."""
    text = " ".join(str(message)[:4 * MAX_ERROR_CHARS].split())
    if len(text) > MAX_ERROR_CHARS:
        text = text[:MAX_ERROR_CHARS - 3] + "..."
    err_console.print(f"error: {text}", markup=False, highlight=False, soft_wrap=True)
    return typer.Exit(code=2)


def progress_bar() -> tuple[Callable[[int, int], None], Callable[[], None]]:
    """A rich progress bar started on the first update: returns ``(update(done, total), stop())``."""
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    prog = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console, transient=False)
    task = None

    def update(done: int, total: int) -> None:
        nonlocal task
        if task is None:
            prog.start()
            task = prog.add_task("running", total=total)
        prog.update(task, completed=done, total=total)

    def stop() -> None:
        if task is not None:
            prog.stop()

    return update, stop
