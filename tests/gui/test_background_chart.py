"""Charts are drawn and rasterised in the window's side process (their matplotlib Python never
holds the window's GIL): only when on screen, again at a new size, the newest draw winning, and a
failing draw says why."""
from __future__ import annotations

import functools
import os

import numpy as np
import pytest

from workbench.gui.mplcanvas import BackgroundChart

RED, BLUE = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)


def fill_by_process(fig, window_pid: int) -> None:
    """Red when drawn in a process other than the window's, blue in the window's own."""
    fig.patch.set_facecolor(RED if os.getpid() != window_pid else BLUE)


def fill(fig, colour) -> None:
    fig.patch.set_facecolor(colour)


def fail(fig) -> None:
    raise ValueError("no data for this chart")


@pytest.fixture
def chart(qtbot):
    widget = BackgroundChart("a chart")
    qtbot.addWidget(widget)
    widget.resize(320, 200)
    return widget


def mean_rgb(grab, widget) -> np.ndarray:
    return grab(widget).reshape(-1, 3).mean(axis=0)


def test_drawn_in_the_side_process_only_once_on_screen(chart, qtbot, grab):
    chart.set_draw(functools.partial(fill_by_process, window_pid=os.getpid()))
    qtbot.wait(200)
    assert chart._worker is None and not chart.is_current()          # hidden: nothing drawn
    with qtbot.waitSignal(chart.drawn, timeout=60_000):
        chart.show()
    r, g, b = mean_rgb(grab, chart)
    assert r > 200 and g < 60 and b < 60                              # red: another process drew it
    assert chart.pixmap().width() == chart.size_px()[0]


def test_a_resize_redraws_and_the_newest_draw_wins(chart, qtbot, grab):
    chart.show()
    qtbot.waitExposed(chart)
    with qtbot.waitSignal(chart.drawn, timeout=60_000):
        chart.set_draw(functools.partial(fill, colour=RED))
        chart.set_draw(functools.partial(fill, colour=BLUE))         # while the red one is drawn
    qtbot.waitUntil(chart.is_current, timeout=60_000)
    r, g, b = mean_rgb(grab, chart)
    assert b > 200 and r < 60
    chart.resize(400, 260)
    qtbot.waitUntil(lambda: chart.is_current() and chart.pixmap().width() == chart.size_px()[0], timeout=60_000)
    assert chart.size_px() == (400, 260)


def test_a_failing_draw_says_why(chart, qtbot):
    chart.show()
    chart.set_draw(fail)
    qtbot.waitUntil(lambda: "chart failed: no data for this chart" in chart.text(), timeout=60_000)
    assert chart._worker is None
