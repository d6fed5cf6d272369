"""Python's cyclic garbage collector runs only on the GUI thread while the window is up.

Automatic collection runs in whichever thread happens to allocate. When that is a worker (the live
pipeline, a sweep, a city generation) and the garbage holds Qt widgets, Qt destroys those widgets
off the GUI thread while the GUI thread paints, and the process dies (measured here with PySide6
6.12: a segmentation fault within seconds). pyqtgraph's GarbageCollector turns automatic collection
off and collects on a timer of the GUI thread instead; stop() (or leaving the `with` block) turns
it back on.
"""
from __future__ import annotations

import gc

GC_INTERVAL_S = 1.0      # how often the GUI thread collects (pyqtgraph's default)


class GuiThreadGarbageCollection:
    """While alive (needs a QApplication): no automatic collection, a GUI-thread timer collects."""

    def __init__(self, interval_s: float = GC_INTERVAL_S):
        from pyqtgraph.util.garbage_collector import GarbageCollector
        self._collector = GarbageCollector(interval=interval_s)

    def stop(self) -> None:
        """Collect once on this (the GUI) thread, then let Python collect automatically again."""
        self._collector.timer.stop()
        gc.collect()
        gc.enable()

    def __enter__(self) -> GuiThreadGarbageCollection:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
