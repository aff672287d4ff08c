"""Named families of pluggable parts (renderers, losses, schedules): a name maps to one
implementation, and an unknown name is an error that lists the known ones."""

from __future__ import annotations

from typing import Callable, Generic, TypeVar

from .errors import RfsdfError

__all__ = ["Registry"]

T = TypeVar("T")


class Registry(Generic[T]):
    """A dict of named entries of one kind (``kind`` names the family in error messages).

    >>> losses = Registry("loss")
    >>> @losses.register("l2")
    ... def l2(a, b): ...
    >>> losses.get("l2") is l2
    True
    """

    def __init__(self, kind: str):
        self.kind = kind
        self._entries: dict[str, T] = {}

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator that files its argument under ``name`` (each name once)."""

        def add(entry: T) -> T:
            if name in self._entries:
                raise ValueError(f"{self.kind} {name!r} is already registered")
            self._entries[name] = entry
            return entry

        return add

    def get(self, name: str) -> T:
        """The entry called ``name``; RfsdfError naming the known ones otherwise."""
        try:
            return self._entries[name]
        except KeyError:
            raise RfsdfError(f"unknown {self.kind} {name!r}; known: {', '.join(self.names())}") from None

    def names(self) -> list[str]:
        return sorted(self._entries)

    def __contains__(self, name: str) -> bool:
        return name in self._entries
