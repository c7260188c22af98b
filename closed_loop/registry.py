"""Registries of interchangeable parts: a read-only name → factory mapping with a one-line error."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Generic, TypeVar

__all__ = ["Registry", "UnknownPartError"]

T = TypeVar("T")


class UnknownPartError(KeyError):
    """A name that no registry entry has; ``str()`` is one line naming the known ones."""

    def __str__(self) -> str:
        return str(self.args[0])


class Registry(Mapping[str, T], Generic[T]):
    """The alternatives of one kind of part, by name (``OBSERVERS["geometric"]``).

    Parameters
    ----------
    part : str
        What the entries are (``"observer"``), used in the error message.
    entries : mapping of str to factory
        Name → class (or function) that builds the part.

    Notes
    -----
    Looking up an unknown name raises :class:`UnknownPartError` (a ``KeyError``) whose message is
    one line: ``unknown registrar 'foo'; known: kabsch, ml, ransac``.
    """

    def __init__(self, part: str, entries: Mapping[str, T]) -> None:
        self._part = part
        self._entries = dict(entries)

    def __getitem__(self, name: str) -> T:
        try:
            return self._entries[name]
        except KeyError:
            known = ", ".join(sorted(self._entries))
            raise UnknownPartError(f"unknown {self._part} {name!r}; known: {known}") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self._part!r}, {sorted(self._entries)})"
