"""Named choices of the agents (policies, batched policies, wrappers, rewards, algorithms, ...): one helper.

Each table of names the command line, ``meta.json`` or a hyperparameter file may give is a
:class:`Registry`: the names in the order they were registered (the order every message and ``--help``
lists them in), each with its value (a class, a one-line formula, a description), and one way to refuse an
unknown name::

    unknown policy 'pid'; choose one of open-loop, odometry-pid, ekf-pid, ekf-pid-traction

A leaf module: it imports nothing of the package, so any agents module can declare its table with it.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Generic, TypeVar

T = TypeVar("T")


class Registry(Generic[T]):
    """Names → values, in registration order, with the one-line error for an unknown name.

    Args:
        what: what a name names, for messages ("policy", "wrapper", ...).
        entries: ``(name, value)`` pairs registered in this order.

    Iterating gives the names; ``name in registry`` tests one.
    """

    def __init__(self, what: str, entries: Iterable[tuple[str, T]] = ()) -> None:
        self.what = what
        self._items: dict[str, T] = {}
        for name, value in entries:
            self.register(name, value)

    def register(self, name: str, value: T) -> T:
        """Add ``name``; a name registered twice is a ValueError (two entries would shadow each other)."""
        if not isinstance(name, str) or not name:
            raise ValueError(f"a {self.what} name must be a non-empty string, got {name!r}")
        if name in self._items:
            raise ValueError(f"{self.what} {name!r} is registered already")
        self._items[name] = value
        return value

    def names(self) -> tuple[str, ...]:
        """The names, in registration order."""
        return tuple(self._items)

    def items(self) -> tuple[tuple[str, T], ...]:
        """``(name, value)`` pairs, in registration order."""
        return tuple(self._items.items())

    def unknown(self, name: object, what: str | None = None, where: str | None = None) -> str:
        """The one-line message for a name that is not registered: ``[WHERE: ]unknown WHAT 'x'; choose one of
        a, b, c`` (``what`` defaults to the registry's)."""
        prefix = f"{where}: " if where else ""
        return f"{prefix}unknown {what or self.what} {name!r}; choose one of {', '.join(self._items)}"

    def check(self, name: object, what: str | None = None, where: str | None = None) -> str:
        """``name`` if it is registered, else ValueError with :meth:`unknown`'s message."""
        if name not in self:
            raise ValueError(self.unknown(name, what, where))
        return name  # type: ignore[return-value]  # a registered name is a str

    def get(self, name: object, what: str | None = None, where: str | None = None) -> T:
        """The value of ``name`` (ValueError with :meth:`unknown`'s message if it is not registered)."""
        return self._items[self.check(name, what, where)]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._items

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f"Registry({self.what!r}: {', '.join(self._items)})"
