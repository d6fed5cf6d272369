"""Python's cyclic garbage collector runs only on the GUI thread while the window is up.

Automatic collection runs in whichever thread happens to allocate. When that is a worker (the live
pipeline, a sweep, a city generation) and the garbage holds Qt widgets, Qt destroys those widgets
off the GUI thread while the GUI thread paints, and the process dies (measured here with PySide6
6.12: a segmentation fault within seconds). So automatic collection is turned off and a timer of
the GUI thread collects instead, the generations CPython itself would have collected by then.

pyqtgraph's GarbageCollector does the same, but it forces a full collection every tenth middle
one, and in the window's process (about 380,000 tracked objects) a full collection holds the GUI
thread for 210–280 ms. Here, as in CPython, a full collection waits until the oldest generation
has grown by a quarter. A burst of new objects (startup, the first render importing Mitsuba)
is collected once and then frozen with everything older (gc.freeze), so no later collection walks
it again.
"""
from __future__ import annotations

import gc

GC_INTERVAL_S = 1.0          # how often the GUI thread looks whether a collection is due
FULL_GROWTH = 0.25           # CPython's rule: a full collection once the oldest generation grew by this
BURST_OBJECTS = 50_000       # this many new objects since the last collection: collect all, then freeze


def due_generation(count: tuple[int, int, int], thresholds: tuple[int, int, int],
                   oldest_now: int, oldest_after_last_full: int) -> int | None:
    """The generation CPython would collect now (None: none), from gc.get_count(), gc.get_threshold()
    and the size of the oldest generation now and right after the last full collection."""
    (c0, c1, c2), (t0, t1, t2) = count, thresholds
    if c0 <= t0:
        return None
    if c2 > t2 and oldest_now - oldest_after_last_full > FULL_GROWTH * oldest_after_last_full:
        return 2
    return 1 if c1 > t1 else 0


class GuiThreadGarbageCollection:
    """While alive (needs a QApplication): no automatic collection; a GUI-thread timer collects.
    stop() (or leaving the `with` block) unfreezes, collects once on this thread and turns
    automatic collection back on."""

    def __init__(self, interval_s: float = GC_INTERVAL_S):
        from PySide6.QtCore import QTimer
        self._thresholds = gc.get_threshold()
        self._oldest_after_full = len(gc.get_objects(generation=2))
        gc.disable()
        self._timer = QTimer()
        self._timer.timeout.connect(self.collect_due)
        self._timer.start(round(1000 * interval_s))

    def collect_due(self) -> int | None:
        """Collect what is due (see due_generation); returns the generation collected.

        After a burst the young generations are collected and every survivor (modules, widgets, a
        project) is frozen: refcounting still frees a frozen object, but one that becomes cyclic
        garbage stays until stop()."""
        count = gc.get_count()
        if count[0] > BURST_OBJECTS:
            gc.collect(1)
            gc.freeze()
            self._oldest_after_full = 0
            return 1
        if count[0] <= self._thresholds[0]:
            return None
        oldest_now = len(gc.get_objects(generation=2)) if count[2] > self._thresholds[2] else 0
        gen = due_generation(count, self._thresholds, oldest_now, self._oldest_after_full)
        gc.collect(gen)
        if gen == 2:
            self._oldest_after_full = len(gc.get_objects(generation=2))
        return gen

    def stop(self) -> None:
        self._timer.stop()
        gc.unfreeze()
        gc.collect()
        gc.enable()

    def __enter__(self) -> GuiThreadGarbageCollection:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
