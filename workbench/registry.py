"""One pattern for every method choice (DESIGN.md §3): a registry of name → function.

A choice made by a parameter (optics level, demosaic method, auto-exposure, …) is a `Registry`;
each method registers itself with `@REGISTRY.register(name)`, callers dispatch with
`REGISTRY[name](…)`, parameter models validate with `REGISTRY.check(name)`, and the window
lists `REGISTRY.names`. An unknown name raises ParameterError naming the parameter and the
registered names.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Mapping
from typing import Generic, TypeVar

from workbench.errors import InvalidValueError, ParameterError

F = TypeVar("F", bound=Callable)


NAME = re.compile(r"[A-Za-z0-9_.\-]{1,40}")


class Registry(Mapping[str, F], Generic[F]):
    """Named implementations of one choice, in registration order.

    field: the parameter that picks among them (dotted, e.g. 'isp.demosaic'); what: a few words
    for the kind of method ('demosaic method'); both appear in the error for an unknown name."""

    def __init__(self, field: str, what: str):
        self.field, self.what = field, what
        self._methods: dict[str, F] = {}

    def register(self, name: str) -> Callable[[F], F]:
        """Decorator: register `fn` under `name` (a second, different function for a name is refused).
        A name is 1–40 characters of letters, digits, '_', '-' and '.', as the project file spells it."""
        if not (isinstance(name, str) and NAME.fullmatch(name)):
            shown = repr(name) if not isinstance(name, str) else repr(name[:40] + ("…" if len(name) > 40 else ""))
            raise ParameterError(f"{self.field} name", shown, "1–40 letters, digits, '_', '-' or '.'")

        def deco(fn: F) -> F:
            if not callable(fn):
                raise InvalidValueError(f"{self.what} '{name}': a function or class is registered, not a "
                                        f"{type(fn).__name__}")
            old = self._methods.get(name)
            if old is not None and (old.__module__, old.__qualname__) != (fn.__module__, fn.__qualname__):
                raise InvalidValueError(f"{self.what} '{name}' is already registered ({old.__module__}.{old.__qualname__})")
            self._methods[name] = fn
            return fn
        return deco

    @property
    def names(self) -> tuple[str, ...]:
        """The registered names, in registration order."""
        return tuple(self._methods)

    def check(self, name: object) -> str:
        """`name` if it is registered, else ParameterError(field, name, the registered names)."""
        if not isinstance(name, str) or name not in self._methods:
            raise ParameterError(self.field, name, f"unknown {self.what}; allowed: {', '.join(self._methods)}")
        return name

    def __getitem__(self, name: str) -> F:
        return self._methods[self.check(name)]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._methods

    def get(self, name, default=None):
        return self._methods.get(name, default) if isinstance(name, str) else default

    def __iter__(self) -> Iterator[str]:
        return iter(self._methods)

    def __len__(self) -> int:
        return len(self._methods)

    def __repr__(self) -> str:
        return f"Registry({self.field!r}: {', '.join(self._methods)})"
