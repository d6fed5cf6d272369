"""The Metrics dock at its default width in a 1280×800 window, comparing A and B (issue 32, item
8): each chart's title fits and overlaps none, its legend covers no data point, the table's B − A
column lies within its viewport, and A and B are named by what differs, on the charts, the
A | B | B − A strip and the table's headers."""
from __future__ import annotations

import pytest
from chart_checks import assert_readable
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PySide6.QtWidgets import QMessageBox

from workbench.project import load_project

MEASURE_TIMEOUT_MS = 300_000


@pytest.fixture
def window(qtbot):
    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    base = load_project("paper_camera")
    win = MainWindow(Document(base.updated(sensor=base.sensor.updated(rows=120, cols=160))), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    qtbot.addWidget(win)
    win.resize(1280, 800)
    win.show()
    qtbot.waitExposed(win)
    qtbot.wait(300)                                  # the first-run layout (the Sensor dock in front)
    return win


def measured(qtbot, panel, project) -> None:
    """Wait until the panel shows the measurement and the read-outs of `project`."""
    qtbot.waitUntil(lambda: panel._worker is None and panel._measured == project and panel._frame is not None
                    and panel._frame.project == project and panel.metrics is not None, timeout=MEASURE_TIMEOUT_MS)


def test_the_metrics_dock_at_1280x800_fits_its_charts_and_table_and_names_a_and_b(window, qtbot):
    from workbench.gui.panels.metrics import COLUMNS, draw_ab
    panel = window.editors["Metrics"]
    window.docks["Metrics"].raise_()
    measured(qtbot, panel, window.document.project)
    panel.pin()
    window.apply_edit("sensor", {"pixel_pitch_um": 1.5})
    measured(qtbot, panel, window.document.project)
    assert 500 <= panel.width() <= 560, panel.width()              # the dock's default width (538 px)

    label_a, label_b = panel.labels()
    assert (label_a, label_b) == ("A: pixel_pitch_um 3", "B: pixel_pitch_um 1.5")
    table = panel.table
    for column in range(1, len(COLUMNS)):                          # A, B, B − A and the verdict, whole
        x = table.columnViewportPosition(column)
        assert not table.isColumnHidden(column) and 0 <= x, COLUMNS[column]
        assert x + table.columnWidth(column) <= table.viewport().width(), (COLUMNS[column], x, table.viewport().width())
    headers = [table.horizontalHeaderItem(c) for c in (1, 2)]
    assert [h.toolTip() for h in headers] == [label_a, label_b]

    for key, view in panel.chart_views.items():
        panel.charts.setCurrentWidget(view)
        qtbot.waitUntil(view.is_current, timeout=60_000)
        fig = view.figure()
        assert_readable(fig)
        texts = " | ".join(t.get_text() for leg in fig.legends for t in leg.get_texts())
        assert label_a in texts and label_b in texts, (key, texts)

    panel.charts.setCurrentWidget(panel.ab)
    w, h = panel.ab.size_px()
    strip = Figure(figsize=(w / 100, h / 100), dpi=100, layout="constrained")
    draw_ab(strip, panel.pinned["srgb"], panel._frame.srgb, panel.labels())
    FigureCanvasAgg(strip).draw()
    assert_readable(strip)
    assert [ax.get_title() for ax in strip.axes[:2]] == [label_a, label_b]
