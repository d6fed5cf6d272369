"""The window on a (small) city project: the 3-D view draws the city, the camera renders
progressively (a low-sample preview first), and moving the camera re-renders from the new pose."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.project import load_project

TIMEOUT_MS = 120_000


def small_city_project():
    p = load_project("city_paper_camera")
    return p.updated(sensor=p.sensor.updated(rows=48, cols=64), render=p.render.updated(spp=4),
                     city=p.city.updated(blocks_x=1, blocks_y=1, n_pedestrians=4, n_trees=4, n_lamps=4,
                                         n_benches=2, n_mailboxes=1))


@pytest.fixture
def city_window(qtbot):
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    win = MainWindow(Document(small_city_project()))
    win.frames_seen = []                     # connected at once: the first render starts with the window
    win.live.frameReady.connect(win.frames_seen.append)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    return win


def full_frame_of(win, project):
    f = win.previews.frame
    return f is not None and not f.preview and f.project == project and not win.live.busy


def full_frame_seen(win, frames):
    """The full frame of the document's project is on screen and has reached `frames` too: the
    window's slot and a test's list each get their own queued call, so one can run before the other."""
    return (full_frame_of(win, win.document.project)
            and any(not f.preview and f.project == win.document.project for f in frames))


def test_city_view_and_panes_draw_and_camera_moves_render_progressively(city_window, qtbot, grab):
    win = city_window
    frames = win.frames_seen
    qtbot.waitUntil(lambda: win.city_view.city is not None, timeout=TIMEOUT_MS)
    qtbot.waitUntil(lambda: full_frame_seen(win, frames), timeout=TIMEOUT_MS)
    win.docks["3-D city"].raise_()           # the saved layout may have another tab of the column in front
    qtbot.waitUntil(lambda: win.city_view.view.isVisible(), timeout=5_000)
    qtbot.waitUntil(win.city_view.view.is_current, timeout=TIMEOUT_MS)
    view = grab(win.city_view.view).astype(float)
    assert view.std() > 10.0, "the 3-D city view looks blank"
    assert len(np.unique(view.reshape(-1, 3), axis=0)) > 50
    for name, pane in win.previews.panes.items():
        assert grab(pane.view_widget).astype(float).std() > 3.0, f"pane {name} looks uniform"
    assert [f.preview for f in frames][:1] == [True]             # a quick preview came first
    assert frames[-1].recomputed[0] == "scene"
    win.city_view.look_through.setChecked(True)
    qtbot.waitUntil(win.city_view.view.is_current, timeout=TIMEOUT_MS)
    through = grab(win.city_view.view)
    assert through.astype(float).std() > 10.0 and not np.array_equal(through, view.astype(np.uint8))
    # "Set pose" with nothing typed changes nothing (the boxes show the pose rounded).
    steps = win.document.undo_stack.count()
    win.city_view.apply_typed_pose()
    assert win.document.undo_stack.count() == steps and "unchanged" in win.city_view.status.text()
    # Move the camera by typing a pose: one undoable edit, a new preview and a new full render.
    box = win.city_view.pose_boxes
    box["pan"].setValue(box["pan"].value() + 30.0)
    frames.clear()
    win.city_view.apply_typed_pose()
    assert win.document.project.pose.mode == "manual"
    qtbot.waitUntil(lambda: full_frame_seen(win, frames), timeout=TIMEOUT_MS)
    assert frames[0].preview and frames[-1].recomputed[0] == "scene"
    frames.clear()
    win.document.undo_stack.undo()
    assert win.document.project == small_city_project()
    qtbot.waitUntil(lambda: full_frame_seen(win, frames), timeout=TIMEOUT_MS)
    assert [f.recomputed for f in frames] == [[]]          # Undo of the move: every stage from the cache
    # Drag the camera's gizmo (the magenta sphere) with the mouse: the camera moves there.
    win.city_view.look_through.setChecked(False)
    before = np.asarray(win.city_view.pose.position_m[:2])   # read first: the view takes the new pose when it is made
    drag_gizmo(qtbot, win.city_view, dx_px=40)
    dropped = win.document.project.pose
    assert dropped.mode == "manual"
    assert np.hypot(*np.subtract(dropped.manual_position_xy_m, before)) > 1.0
    # A drag from anywhere but the visible gizmo orbits the view and leaves the camera alone.
    assert_a_drag_off_the_gizmo_orbits(qtbot, win.city_view)


def assert_a_drag_off_the_gizmo_orbits(qtbot, city_view) -> None:
    """A left drag from the view's middle (where the gizmo is not drawn: picked through the depth
    buffer, so a gizmo hidden behind a building there does not count) adds no edit."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest

    from workbench.gui.city_view import visible_actor_at
    view, got = city_view.view, {}
    qtbot.wait(500)                               # the dropped pose's redraw is posted
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    dpr = view.devicePixelRatioF()
    mid = QPoint(view.width() // 2, view.height() // 2)

    def probe(pl):
        got["gizmo_there"] = visible_actor_at(pl, round(mid.x() * dpr), round((view.height() - mid.y()) * dpr)) \
            is city_view._gl.get("gizmo")
        got["camera"] = tuple(pl.camera.position)
    view.call(probe)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert not got["gizmo_there"], "the gizmo is drawn in the middle of the view; move the probe"
    camera = got["camera"]
    steps, pose = city_view.document.undo_stack.index(), city_view.document.project.pose
    QTest.mousePress(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, mid)
    for k in range(1, 5):
        QTest.mouseMove(view, mid + QPoint(30 * k, 8 * k))
    QTest.mouseRelease(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, mid + QPoint(120, 30))
    qtbot.wait(300)
    view.call(probe)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    assert city_view.document.undo_stack.index() == steps and city_view.document.project.pose == pose
    assert np.linalg.norm(np.subtract(got["camera"], camera)) > 0.5, "the drag did not orbit the view"


def drag_gizmo(qtbot, city_view, dx_px: int) -> None:
    """Press on the gizmo where the 3-D view draws it, drag it sideways and drop it."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest
    view, got = city_view.view, {}

    def locate(pl, centre=tuple(float(v) for v in city_view.pose.position_m)):
        pl.renderer.SetWorldPoint(*centre, 1.0)
        pl.renderer.WorldToDisplay()
        got["xy"] = pl.renderer.GetDisplayPoint()[:2]
    view.call(locate)
    qtbot.waitUntil(view.is_current, timeout=TIMEOUT_MS)
    dpr = view.devicePixelRatioF()
    x, y = got["xy"]
    at = QPoint(round(x / dpr), round((view._physical_size()[1] - 1 - y) / dpr))
    assert view.rect().contains(at), f"the gizmo is not in the view: {at}"
    steps = city_view.document.undo_stack.index()
    QTest.mousePress(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, at)
    for step in range(1, 5):
        QTest.mouseMove(view, at + QPoint(step * dx_px // 4, 0))
    QTest.mouseRelease(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, at + QPoint(dx_px, 0))
    qtbot.waitUntil(lambda: city_view.document.undo_stack.index() > steps, timeout=TIMEOUT_MS)


@pytest.mark.parametrize("representation", ["bands", "sensor"])
def test_sensor_edits_on_a_city_run_only_the_sensor_stages(qtbot, representation):
    """A CFA, fill-factor or ISP edit reuses the city render: the window renders spectrally (a
    sensor-channel film is rendered as bands there) and the sensor stage integrates the spectrum."""
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    project = small_city_project()
    project = project.updated(render=project.render.updated(representation=representation))
    win = MainWindow(Document(project), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    qtbot.addWidget(win)
    win.show()
    qtbot.waitUntil(lambda: full_frame_of(win, win.document.project), timeout=TIMEOUT_MS)
    first = win.previews.frame
    for section, change, recomputed in (("sensor", {"cfa_pattern": "RGGB"}, ["signal", "sensor", "isp"]),
                                        ("sensor", {"fill_factor": 0.5}, ["signal", "sensor", "isp"]),
                                        ("isp", {"demosaic": "malvar2004"}, ["isp"])):
        frames = []
        win.live.frameReady.connect(frames.append)
        assert win.apply_edit(section, change)
        qtbot.waitUntil(lambda: full_frame_seen(win, frames), timeout=TIMEOUT_MS)
        win.live.frameReady.disconnect(frames.append)
        assert [f.preview for f in frames] == [False], "no preview render: the scene is not rendered again"
        assert frames[-1].recomputed == recomputed
    assert win.previews.frame.irradiance_photons is first.irradiance_photons        # the same render, reused


def test_cfa_edits_that_move_the_films_bands_render_nothing(qtbot, monkeypatch):
    """Bayer → RCCC → RCCB → Bayer moves the film's range (390 → 385 nm and back) and re-rendered
    the city each way (issue 32 item 7): the window renders bands every pattern's bands are sums
    of (render.shared_bands), so after the first frame no edit asks the render worker for anything
    and none shows a quick look; each pattern's frame is on its own bands."""
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.render.render_worker import RenderWorker
    asked = []
    render = RenderWorker.job

    def counted(self, *args, **kwargs):
        asked.append(args[1].index)
        return (yield from render(self, *args, **kwargs))
    monkeypatch.setattr(RenderWorker, "job", counted)
    win = MainWindow(Document(small_city_project()), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    qtbot.addWidget(win)
    win.show()
    qtbot.waitUntil(lambda: full_frame_of(win, win.document.project), timeout=TIMEOUT_MS)
    assert asked, "the first frame was not rendered by the worker"
    asked.clear()
    first_nm = {}
    for cfa, recomputed in (("RCCC", ["scene", "optics", "signal", "sensor", "isp"]),   # the scene: a band sum
                            ("RCCB", ["signal", "sensor", "isp"]), ("GRBG", [])):
        frames = []
        win.live.frameReady.connect(frames.append)
        assert win.apply_edit("sensor", {"cfa_pattern": cfa})
        qtbot.waitUntil(lambda: full_frame_seen(win, frames), timeout=TIMEOUT_MS)
        win.live.frameReady.disconnect(frames.append)
        assert [f.preview for f in frames] == [False], f"{cfa}: a quick look was rendered"
        assert frames[-1].recomputed == recomputed, cfa
        first_nm[cfa] = float(frames[-1].wavelengths_nm[0])
    assert asked == [], f"CFA edits asked the render worker for frames {asked}"
    assert first_nm["RCCC"] == first_nm["RCCB"] < first_nm["GRBG"]


def test_a_pose_edit_reuses_the_shown_city_and_gets_the_same_pose():
    """A camera move only samples the pose on the city already shown: the same pose as generating
    the city again, for a sampled (target) and a typed (manual) pose."""
    from workbench.gui.city_view import city_and_pose
    project = small_city_project()
    city, pose = city_and_pose(project)
    for edited in (project.updated(seed=project.seed),
                   project.updated(pose=project.pose.updated(mode="manual", manual_position_xy_m=(3.0, 40.0),
                                                             manual_pan_deg=15.0))):
        again_city, again = city_and_pose(edited)
        reused_city, reused = city_and_pose(edited, city)
        assert reused_city is city
        assert np.array_equal(again.position_m, reused.position_m)
        assert (again.pan_deg, again.tilt_deg, again.roll_deg) == (reused.pan_deg, reused.tilt_deg, reused.roll_deg)



def test_a_camera_dropped_inside_a_building_is_refused_and_goes_back(city_window, qtbot):
    """A gizmo drop inside a building put the camera there (a black frame, nothing said): it is
    refused with the reason, no edit is made, and the boxes show the camera where it was."""
    win = city_window
    qtbot.waitUntil(lambda: win.city_view.city is not None and win.city_view.pose is not None, timeout=TIMEOUT_MS)
    view = win.city_view
    building = next(o for o in view.city.objects if o.class_name == "building" and o.footprint_xy is not None)
    x, y = np.asarray(building.footprint_xy, dtype=float).mean(axis=0)
    before, steps = win.document.project, win.document.undo_stack.count()
    view._gizmo_moved((float(x), float(y), 1.5))
    assert "inside a building" in view.status.text() and win.document.project == before
    assert win.document.undo_stack.count() == steps
    assert view.pose_boxes["x"].value() == pytest.approx(view.pose.position_m[0], abs=0.01)
