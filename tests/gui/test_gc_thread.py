"""Cyclic garbage that holds widgets is freed on the GUI thread, never by a worker thread that
happens to allocate (Qt crashes when a worker destroys widgets while the GUI thread paints)."""
from __future__ import annotations

import gc
import threading


def test_a_worker_allocating_does_not_collect_widgets(qapp, qtbot):
    from PySide6.QtWidgets import QComboBox, QWidget
    freed_on_gui_thread = []

    class Tag:
        def __del__(self):
            freed_on_gui_thread.append(threading.current_thread() is threading.main_thread())

    for _ in range(20):
        widget = QWidget()
        QComboBox(widget)
        widget.cycle = widget            # only the cyclic collector can free it
        widget.tag = Tag()
    del widget

    kept = []

    def allocate():                      # far past every generation's automatic threshold
        kept.extend([i] for i in range(100_000))
    worker = threading.Thread(target=allocate)
    worker.start()
    worker.join()
    assert not gc.isenabled()
    assert freed_on_gui_thread == []
    qtbot.waitUntil(lambda: len(freed_on_gui_thread) == 20, timeout=10_000)
    assert all(freed_on_gui_thread)
