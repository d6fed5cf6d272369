"""Cyclic garbage that holds widgets is freed on the GUI thread, never by a worker thread that
happens to allocate (Qt crashes when a worker destroys widgets while the GUI thread paints); the
GUI thread collects the generations CPython would have, a full collection only once the oldest
generation grew by a quarter, and a burst of new objects is collected once and then frozen."""
from __future__ import annotations

import gc
import threading
from pathlib import Path

import pytest

from workbench.gui.gc_thread import due_generation


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


@pytest.mark.parametrize(("count", "oldest_now", "expected"), [
    ((700, 11, 11), 1300, None),       # the youngest generation has not reached its threshold
    ((701, 3, 3), 1300, 0),
    ((701, 11, 3), 1300, 1),
    ((701, 11, 11), 1200, 1),          # the oldest grew 20 %: the middle generation only
    ((701, 11, 11), 1300, 2),          # grew 30 %: a full collection
])
def test_a_full_collection_waits_until_the_oldest_generation_grew_by_a_quarter(count, oldest_now, expected):
    assert due_generation(count, (700, 10, 10), oldest_now, 1000) == expected


def test_a_burst_is_collected_once_then_frozen(gc_on_gui_thread):
    gc_on_gui_thread.collect_due()                   # whatever is due from earlier
    frozen_before = gc.get_freeze_count()
    burst = [[i] for i in range(60_000)]
    assert gc_on_gui_thread.collect_due() == 1
    assert gc.get_freeze_count() >= frozen_before + len(burst)
    assert gc.get_count()[0] < 100
    frozen_after_burst = gc.get_freeze_count()       # the burst and whatever older was not frozen yet
    small = [[i] for i in range(1_000)]
    assert gc_on_gui_thread.collect_due() in (0, 1, 2)    # an ordinary collection: no new freeze
    assert gc.get_freeze_count() == frozen_after_burst
    assert len(small) == 1_000


def test_the_gui_starts_threads_only_through_superqt_workers_or_the_live_runner():
    """A plain thread whose closure holds a widget can drop the widget's last reference off the GUI
    thread. superqt's workers hold none; LiveRunner's thread holds only the runner, a QObject its
    window owns; the 3-D view's render thread holds only its _RenderLoop (a plain object) and the
    relay the view keeps too."""
    import workbench.gui
    package = Path(workbench.gui.__file__).parent
    starts = sorted(str(p.relative_to(package)) for p in package.rglob("*.py") if "threading.Thread(" in p.read_text())
    assert starts == ["live.py", "vtk_view.py"]
