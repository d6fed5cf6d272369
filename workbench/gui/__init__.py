"""The Qt application (PySide6, pyqtgraph, superqt): the only package that imports Qt.

Every computation stays in the core; this package shows it and turns user actions into project
edits. Entry point: workbench.gui.app.main (`workbench gui [PROJECT]`)."""
from __future__ import annotations

import sys


def _guard_singleton_refcount_bug() -> None:
    """PySide6/shiboken6 6.12.0 on CPython < 3.12 returns None (from every void method such as
    setText or resize) and True (from Signal.emit) without taking a reference, so each call drops
    one reference to None or True, and after a few hundred calls the interpreter aborts with
    "none_dealloc: deallocating None" (measured here: −1 reference per call). CPython 3.12 made
    these singletons immortal; where probe calls show the leak, do the same by giving them a
    reference count no session can use up."""
    if sys.version_info >= (3, 12):
        return
    import ctypes

    from PySide6.QtCore import QObject, Signal

    class _Probe(QObject):
        ping = Signal()

    probe = _Probe()
    for singleton, call in ((None, lambda: probe.setObjectName("probe")), (True, probe.ping.emit)):
        before = sys.getrefcount(singleton)
        call()
        if sys.getrefcount(singleton) < before:
            ctypes.c_ssize_t.from_address(id(singleton)).value += 1 << 40


_guard_singleton_refcount_bug()
