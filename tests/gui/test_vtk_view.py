"""The off-screen 3-D view: drawn on its own thread, shown as an image, driven by forwarded mouse
events."""
import threading

import numpy as np
import pytest

pytestmark = pytest.mark.gui
TIMEOUT_MS = 30_000


@pytest.fixture
def view(qtbot):
    import pyvista as pv

    from workbench.gui.vtk_view import OffscreenPlotterView
    v = OffscreenPlotterView()
    qtbot.addWidget(v)
    v.resize(320, 240)
    v.show()
    v.call(lambda pl: pl.add_mesh(pv.Sphere(radius=1.0), color="orange"))
    v.call(lambda pl: pl.reset_camera())
    qtbot.waitUntil(v.is_current, timeout=TIMEOUT_MS)
    yield v
    v.close_view()


def _camera(qtbot, v) -> tuple:
    got = {}
    v.call(lambda pl: got.update(position=tuple(pl.camera.position)))
    qtbot.waitUntil(v.is_current, timeout=TIMEOUT_MS)
    return got["position"]


def test_the_view_shows_what_its_thread_rendered_at_the_widgets_size(view, qtbot, grab):
    image = grab(view).astype(float)
    assert image.std() > 10.0, "the view looks blank"
    centre = image[100:140, 140:180].reshape(-1, 3).mean(axis=0)
    assert centre[0] > 150 and centre[2] < 100, f"the orange sphere is not in the middle: {centre}"
    assert (view.image.width(), view.image.height()) == view._physical_size()
    threads = []
    view.call(lambda pl: threads.append(threading.current_thread()))
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert threads and threads[0] is not threading.main_thread()
    view.resize(400, 200)
    qtbot.waitUntil(lambda: view.is_current() and view.image.width() == view._physical_size()[0],
                    timeout=TIMEOUT_MS)


def test_a_mouse_drag_rotates_and_the_wheel_zooms(view, qtbot):
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest
    before = np.array(_camera(qtbot, view))
    QTest.mousePress(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, QPoint(160, 120))
    for x in range(165, 260, 10):
        QTest.mouseMove(view, QPoint(x, 120))
    QTest.mouseRelease(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, QPoint(260, 120))
    rotated = np.array(_camera(qtbot, view))
    assert np.linalg.norm(rotated - before) > 0.5, "the drag did not rotate the camera"
    assert np.linalg.norm(rotated) == pytest.approx(np.linalg.norm(before), rel=1e-6)   # an orbit
    from PySide6.QtCore import QPointF
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication
    wheel = QWheelEvent(QPointF(160, 120), QPointF(view.mapToGlobal(QPoint(160, 120))), QPoint(0, 0),
                        QPoint(0, 120), Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier,
                        Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(view, wheel)
    zoomed = np.array(_camera(qtbot, view))
    assert np.linalg.norm(zoomed) < np.linalg.norm(rotated) - 1e-3, "the wheel did not zoom in"


def _drag(view, start: tuple[int, int], dx: int, during=None) -> None:
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest
    at = QPoint(*start)
    QTest.mousePress(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, at)
    for k in range(1, 5):
        QTest.mouseMove(view, at + QPoint(k * dx // 4, 0))
    if during is not None:
        during()
    QTest.mouseRelease(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, at + QPoint(dx, 0))


def test_a_camera_drag_draws_a_quarter_of_the_pixels_and_the_full_view_on_release(view, qtbot):
    """Orbiting re-renders at INTERACTIVE_PIXEL_FRACTION of the pixels (a software OpenGL's cost is
    per pixel), painted over the whole view; the release draws the full size again."""
    from workbench.gui.vtk_view import INTERACTIVE_PIXEL_FRACTION
    full = view._physical_size()
    sizes = []

    def held():
        qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
        sizes.append((view.image.width(), view.image.height()))
    _drag(view, (160, 120), 80, during=held)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert sizes[0][0] * sizes[0][1] == pytest.approx(INTERACTIVE_PIXEL_FRACTION * full[0] * full[1], rel=0.05)
    assert (view.image.width(), view.image.height()) == full


def test_a_claimed_drag_goes_to_its_handler_and_the_camera_stays(view, qtbot):
    before = _camera(qtbot, view)
    calls = []
    view.set_drag_handler(lambda pl, x, y, phase: calls.append((phase, x, y)) or True)
    _drag(view, (160, 120), 80)
    assert _camera(qtbot, view) == before, "a claimed drag moved the camera"
    assert [c[0] for c in calls][:1] == ["press"] and calls[-1][0] == "release"
    assert calls[0][1:] == (160, 239 - 120) and calls[-1][1:] == (240, 239 - 120)
    view.set_drag_handler(lambda pl, x, y, phase: False)     # declined at the press: the camera orbits
    _drag(view, (160, 120), 80)
    assert np.linalg.norm(np.subtract(_camera(qtbot, view), before)) > 0.5


def test_the_visible_actor_is_picked_through_the_depth_buffer(view, qtbot):
    """A sphere hidden behind a box is not what a press on it picks (the city view's gizmo rule)."""
    import pyvista as pv

    from workbench.gui.city_view import visible_actor_at
    got = {}

    def scene(pl):
        pl.clear()
        got["sphere"] = pl.add_mesh(pv.Sphere(radius=0.5, center=(0, 0, 0)), color="magenta")
        pl.camera.position, pl.camera.focal_point, pl.camera.up = (0, 0, 10), (0, 0, 0), (0, 1, 0)
        pl.reset_camera_clipping_range()
        x, y = pl.window_size[0] // 2, pl.window_size[1] // 2
        got["alone"] = visible_actor_at(pl, x, y)
        got["box"] = pl.add_mesh(pv.Cube(center=(0, 0, 3), x_length=3, y_length=3, z_length=0.5))
        pl.reset_camera_clipping_range()
        got["hidden"] = visible_actor_at(pl, x, y)
        got["beside"] = visible_actor_at(pl, 2, 2)
    view.call(scene)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert got["alone"] is got["sphere"]
    assert got["hidden"] is got["box"]
    assert got["beside"] is None


def test_mouse_moves_queued_while_the_thread_is_busy_are_merged(view, qtbot):
    """A render thread behind the mouse runs only the newest move, not every one it missed."""
    from PySide6.QtCore import QPoint
    from PySide6.QtTest import QTest
    busy, gate, moves = threading.Event(), threading.Event(), []
    qtbot.waitExposed(view)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)   # the window's own first commands (a resize)
    view.call(lambda pl: pl.iren.interactor.AddObserver("MouseMoveEvent",
                                                        lambda o, _e: moves.append(o.GetEventPosition())))
    view.call(lambda pl: (busy.set(), gate.wait(10)))
    assert busy.wait(10)
    for x in range(100, 200, 10):
        QTest.mouseMove(view, QPoint(x, 100))
    qtbot.wait(100)                                  # every move delivered to the widget
    gate.set()
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert moves == [(190, 239 - 100)]              # the newest only (VTK counts y from the bottom)


def test_a_failing_command_is_reported_and_the_view_goes_on(view, qtbot):
    frames, reported = view.frames_rendered, []
    view.failed.connect(reported.append)
    view.call(lambda pl: 1 / 0)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert "ZeroDivisionError" in view.last_error and view.frames_rendered > frames
    assert reported == [view.last_error]                 # the city view shows it in its status line
    view.render()
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)


def test_close_view_ends_its_thread(view):
    view.close_view()
    assert not view._thread.is_alive()


def test_the_view_draws_without_an_x_server_on_qts_offscreen_platform(tmp_path):
    """No GL widget and no native window: with Qt's offscreen platform and no DISPLAY the view
    still draws (VTK falls back from X to EGL on its own)."""
    import os
    import subprocess
    import sys
    script = """
import time
from PySide6.QtWidgets import QApplication
app = QApplication([])
import pyvista as pv
from workbench.gui.vtk_view import OffscreenPlotterView
v = OffscreenPlotterView()
v.resize(200, 150)
v.show()
v.call(lambda pl: pl.add_mesh(pv.Sphere(), color="orange"))
v.call(lambda pl: pl.reset_camera())
end = time.time() + 60
while not v.is_current() and time.time() < end:
    app.processEvents()
c = v.grab().toImage().pixelColor(100, 75)
print("centre", c.red(), c.green(), c.blue())
v.close_view()
"""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["QT_QPA_PLATFORM"] = "offscreen"
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("centre")]
    assert line, out.stdout + out.stderr
    r, g, b = map(int, line[0].split()[1:])
    assert r > 150 and b < 100, f"the sphere is not drawn: {r, g, b}"



@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="per-thread niceness is Linux's")
def test_the_render_thread_and_the_threads_it_starts_yield_to_the_gui(view, qtbot):
    """The render thread runs at VIEW_THREAD_NICE, and so does a thread it starts (as a software
    OpenGL such as Mesa's llvmpipe starts its own), so a redraw cannot take the cores from the GUI."""
    import os

    from workbench.gui.vtk_view import VIEW_THREAD_NICE

    def niceness() -> int:
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    seen = {}

    def on_render_thread(_pl):
        seen["render"] = niceness()
        child = threading.Thread(target=lambda: seen.update(child=niceness()))
        child.start()
        child.join()
    view.call(on_render_thread)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    gui = niceness()
    assert seen["render"] == min(19, gui + VIEW_THREAD_NICE)
    assert seen["child"] == seen["render"]
