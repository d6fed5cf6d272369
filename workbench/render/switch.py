"""A feature that a with-block turns off: the render-noise benchmark renders its 'before' with the
same scene code (portal_guide.unguided, tunnel_sun_share.separate_sun)."""
from __future__ import annotations

from contextlib import contextmanager


class Switch:
    """On unless inside one or more `off()` blocks (nestable)."""

    def __init__(self):
        self._stack = [True]

    @property
    def on(self) -> bool:
        return self._stack[-1]

    @contextmanager
    def off(self):
        self._stack.append(False)
        try:
            yield
        finally:
            self._stack.pop()
