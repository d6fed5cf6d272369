"""Responsiveness of the window (`workbench bench gui`), measured on the real widgets.

* GUI-thread stalls: a 5 ms QTimer on the GUI thread records the gaps between its ticks while
  background work runs — a city render in the live worker, an exposure sweep in the sweep panel,
  an experiment-like process started by the experiments panel, and all three at once.
* Edit-to-pane latency at 640×480 (paper camera): from the edit to the sRGB pane having painted
  the new frame (the window's repaint, which paints every changed pane in one pass), for an ISP
  edit (ISP re-runs) and a sensor edit (exposure + ISP re-run), each with the longest GUI-thread
  tick gap during it; on the city: a CFA edit (a sensor-stage run on the cached render) and Undo
  of a camera move (from the stage cache).
* Camera moves on the city (and on a 640×480 one): the quick-look preview on screen, the refined
  frame, and the longest GUI stall while both render (in the render worker process); "Colour by
  class" switched on and off.
* 3-D view frames per second with the full city of the city sample: orbiting by a mouse drag
  (the interactive level of detail) and turned at full size.
* First views: every dock and every tab inside it shown once (a lens file, so the lens charts
  compute), the longest GUI stall and the longest wait for a chart to be on screen.
With --load N, N busy processes (one core each) run during every measurement.
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time

import numpy as np

from workbench.files import json_text

TICK_MS = 5


class TickRecorder:
    """Gaps (ms) between ticks of a GUI-thread timer."""

    def __init__(self):
        from PySide6.QtCore import Qt, QTimer
        self.timer = QTimer()
        self.timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.timer.setInterval(TICK_MS)
        self.timer.timeout.connect(self._tick)
        self.gaps_ms: list[float] = []
        self._last = None

    def _tick(self) -> None:
        now = time.perf_counter()
        if self._last is not None:
            self.gaps_ms.append(1e3 * (now - self._last))
        self._last = now

    def start(self) -> None:
        """Start ticking; the first gap counts from now, so a stall while a job starts is seen."""
        self.gaps_ms, self._last = [], time.perf_counter()
        self.timer.start()

    def stop(self) -> dict:
        self.timer.stop()
        g = np.asarray(self.gaps_ms or [0.0])
        return {"max_gap_ms": round(float(g.max()), 1), "p99_gap_ms": round(float(np.percentile(g, 99)), 1),
                "median_gap_ms": round(float(np.median(g)), 1), "ticks": int(g.size)}


def _wait(app, predicate, timeout_s: float) -> bool:
    """Run the Qt event loop (idle in the loop, as an application is) until predicate() holds."""
    from PySide6.QtCore import QEventLoop, QTimer
    deadline = time.perf_counter() + timeout_s
    loop = QEventLoop()
    check = QTimer()
    check.setInterval(2)

    def poll():
        if predicate() or time.perf_counter() > deadline:
            loop.quit()
    check.timeout.connect(poll)
    check.start()
    if not predicate():
        loop.exec()
    check.stop()
    return predicate()


def _window(project):
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    win = MainWindow(Document(project))
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.show()
    return win


def _full_frame(win):
    f = win.previews.frame
    return f is not None and not f.preview and f.project == win.document.project and not win.live.busy


class PaintWatcher:
    """Counts the paint events of a widget (an event filter), so a measurement can end when the
    new pixels have been painted rather than when the frame was handed to the panes."""

    def __init__(self, widget):
        from PySide6.QtCore import QEvent, QObject

        class _Filter(QObject):
            def eventFilter(inner, obj, event):
                if event.type() == QEvent.Type.Paint:
                    self.paints += 1
                return False
        self.paints = 0
        self._filter = _Filter()
        self.widget = widget
        widget.installEventFilter(self._filter)

    def remove(self) -> None:
        self.widget.removeEventFilter(self._filter)


def edit_latency_ms(app, win, section: str, values: list[dict], timeout_s: float = 60,
                    stalls: list | None = None) -> list[float]:
    """Edit → the sRGB pane has painted the resulting frame and the window is flushed (ms), once
    per value; with `stalls`, the longest GUI tick gap of each edit is appended to it."""
    out = []
    ticks = TickRecorder()
    watcher = PaintWatcher(win.previews.panes["srgb"].view_widget.viewport())
    try:
        for changes in values:
            shown, paints = win.previews.frames_shown, watcher.paints
            ticks.start()
            t0 = time.perf_counter()
            win.apply_edit(section, changes)
            if not _wait(app, lambda: win.previews.frames_shown > shown and _full_frame(win), timeout_s):
                raise TimeoutError(f"no frame after the {section} edit {changes}")
            app.processEvents()                        # the window's pending repaint, if not done yet
            if watcher.paints == paints:               # not painted since the edit: paint it now
                win.previews.panes["srgb"].view_widget.viewport().repaint()
            out.append(1e3 * (time.perf_counter() - t0))
            gap = ticks.stop()["max_gap_ms"]
            if stalls is not None:
                stalls.append(gap)
    finally:
        watcher.remove()
    return out


def _latency_row(name: str, values: list[float], stalls: list[float], goal_ms: float) -> dict:
    return {"measure": name, "median_ms": round(statistics.median(values), 1), "max_ms": round(max(values), 1),
            "goal_ms": goal_ms, "max_stall_ms": round(max(stalls), 1), "goal_stall_ms": 100, "runs": len(values)}


def camera_moves(app, win, n: int) -> list[dict]:
    """n camera moves (the pan box +15°, Set pose): time to the preview on screen and to the
    refined frame, and the longest GUI stall, one row each."""
    ticks = TickRecorder()
    rows = []
    rows_px, cols_px = win.document.project.sensor.rows, win.document.project.sensor.cols
    for i in range(n):
        frames = []
        win.live.frameReady.connect(frames.append)
        box = win.city_view.pose_boxes["pan"]
        box.setValue(box.value() + 15.0)
        ticks.start()
        t0 = time.perf_counter()
        win.city_view.apply_typed_pose()
        _wait(app, lambda: any(f.preview for f in frames) and win.previews.frame is not None
              and win.previews.frame.preview, 120)
        t_preview = time.perf_counter() - t0
        _wait(app, lambda: _full_frame(win), 600)
        stall = ticks.stop()["max_gap_ms"]
        win.live.frameReady.disconnect(frames.append)
        rows.append({"measure": f"camera move {i + 1} ({cols_px}×{rows_px}): preview on screen, then refined",
                     "preview_s": round(t_preview, 2), "refined_s": round(time.perf_counter() - t0, 2),
                     "max_stall_ms": stall, "goal_preview_s": 1.0, "goal_stall_ms": 100,
                     "preview_spp": win.live.preview_spp, "refined_spp": win.document.project.render.spp})
    return rows


def first_views(app, win) -> dict:
    """Show every dock and every tab inside it once, as a new user does: the longest GUI tick gap
    of any first view (which view), and the longest wait for a chart to be on screen."""
    from PySide6.QtWidgets import QTabWidget

    from workbench.gui.mplcanvas import BackgroundChart

    def shown_chart(widget):
        return next((c for c in widget.findChildren(BackgroundChart) if c.isVisible()), None)
    steps = []
    for title, dock in win.docks.items():
        steps.append((title, lambda d=dock: (d.raise_(), shown_chart(d.widget()))[1]))
        for tabs in dock.widget().findChildren(QTabWidget):
            for i in range(tabs.count()):
                steps.append((f"{title} / {tabs.tabText(i)}", lambda t=tabs, i=i: (
                    t.setCurrentIndex(i), t.widget(i) if isinstance(t.widget(i), BackgroundChart) else shown_chart(t.widget(i)))[1]))
    ticks = TickRecorder()
    gaps, chart_s = [], []
    for name, show in steps:
        ticks.start()
        t0 = time.perf_counter()
        chart = show()
        if chart is not None and chart._draw is not None:
            _wait(app, chart.is_current, 60)
            chart_s.append(time.perf_counter() - t0)
        _wait(app, lambda: False, 0.5)
        gaps.append((ticks.stop()["max_gap_ms"], name))
    worst = max(gaps)
    return {"measure": "first view of every dock and tab (a lens file: its charts)", "max_stall_ms": worst[0],
            "goal_stall_ms": 100, "worst_view": worst[1], "views": len(steps),
            "slowest_chart_on_screen_s": round(max(chart_s), 2) if chart_s else None}


def cpu_hogs(n: int) -> list:
    """n busy processes (one core each): the load the window must stay responsive under."""
    import subprocess
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def orbit_fps(app, city_view, frames: int, mouse: bool = True) -> float:
    """Frames per second while the 3-D view orbits the city, each step waited for until its image
    is on the GUI thread. mouse: a left drag from near the view's corner (real mouse events: the
    view draws the interactive level of detail); else camera turns posted to the render thread
    (the full-size frame)."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtTest import QTest
    view = city_view.view
    start = QPoint(view.width() // 8, view.height() // 8)
    if mouse:
        QTest.mousePress(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, start)
    t0 = time.perf_counter()
    for k in range(frames):
        if mouse:
            QTest.mouseMove(view, start + QPoint(2 * (k + 1), 0))
        else:
            view.call(lambda pl: pl.camera.Azimuth(3.0))
        _wait(app, view.is_current, 30)
    fps = frames / (time.perf_counter() - t0)
    if mouse:
        QTest.mouseRelease(view, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier,
                           start + QPoint(2 * frames, 0))
        _wait(app, view.is_current, 30)
    return fps


def run(quick: bool = False, load: int = 0) -> dict:
    from PySide6.QtWidgets import QApplication

    import workbench.gui  # noqa: F401  (PySide6 refcount guard)
    from workbench.gui.gc_thread import GuiThreadGarbageCollection
    app = QApplication.instance() or QApplication(["workbench-bench"])
    hogs = cpu_hogs(load)
    try:
        with GuiThreadGarbageCollection():
            out = _measure(app, quick)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    out["notes"].append(f"load: {load} busy process(es) during every measurement; "
                        f"{len(__import__('os').sched_getaffinity(0))} cores")
    return out


def _measure(app, quick: bool) -> dict:
    from workbench.project import load_project
    rows = []
    notes = []

    # -- first views of the docks, tabs and charts, at 1280×800 ---------------------------------
    paper = load_project("paper_camera")
    win = _window(paper.updated(optics=paper.optics.updated(lens_file="automotive.2.4mm.json")))
    win.resize(1280, 800)
    if not _wait(app, lambda: _full_frame(win), 120):
        raise TimeoutError("the first frame with a lens file did not arrive")
    rows.append(first_views(app, win))
    win.document.undo_stack.setClean()
    win.close()
    app.processEvents()

    # -- edit-to-pane latency at 640×480 ---------------------------------------------------
    win = _window(paper)
    if not _wait(app, lambda: _full_frame(win), 120):
        raise TimeoutError("the paper camera's first frame did not arrive")
    n = 3 if quick else 7
    isp_stalls, sensor_stalls = [], []
    isp = edit_latency_ms(app, win, "isp", [{"illuminant_correction": v} for v in
                                            (["white_world", "gray_world"] * n)[:n]], stalls=isp_stalls)
    sensor = edit_latency_ms(app, win, "sensor", [{"analog_gain": 1.0 + 0.1 * (i + 1)} for i in range(n)],
                             stalls=sensor_stalls)
    rows.append(_latency_row("edit→pane, ISP edit, 640×480", isp, isp_stalls, 50))
    rows.append(_latency_row("edit→pane, sensor edit, 640×480", sensor, sensor_stalls, 80))
    metrics = win.editors.get("Metrics")
    if metrics is not None:                  # the Metrics dock in front: an edit re-measures the camera
        win.docks["Metrics"].raise_()
        _wait(app, lambda: metrics._worker is None, 120)
        done = []
        metrics.measured.connect(done.append)
        ticks = TickRecorder()
        ticks.start()
        win.apply_edit("sensor", {"analog_gain": 2.5})
        _wait(app, lambda: bool(done), 180)
        stats = ticks.stop()
        rows.append({"measure": "Metrics dock: edit → MTF, SNR, ΔE re-measured (worker thread)", **stats,
                     "goal_max_gap_ms": 100, "job_s": round(done[0]["seconds"], 2) if done else None})
    sweep = win.editors.get("Exposure sweep")
    experiments = win.editors.get("Experiments")
    win.document.undo_stack.setClean()
    win.close()

    # -- GUI-thread stalls under background work, and 3-D orbit speed ------------------------
    city = load_project("city_paper_camera")
    size = (120, 160) if quick else (240, 320)
    city = city.updated(sensor=city.sensor.updated(rows=size[0], cols=size[1]),
                        render=city.render.updated(spp=16 if quick else 64))
    win = _window(city)
    if not _wait(app, lambda: win.city_view.city is not None and _full_frame(win), 600):
        raise TimeoutError("the city project's first frame did not arrive")
    sweep = win.editors.get("Exposure sweep")
    experiments = win.editors.get("Experiments")
    ticks = TickRecorder()
    out_dir = tempfile.mkdtemp(prefix="workbench-bench-gui-")

    def start_render():
        win.apply_edit("render", {"seed": win.document.project.render.seed + 1})

    def start_sweep():
        if sweep is not None:
            sweep.run()

    def start_experiment():
        if experiments is not None:
            experiments.run_argv([sys.executable, "-m", "workbench.cli", "simulate", "paper_camera",
                                  "--out", out_dir], out_dir)

    def busy():
        return (win.live.busy or (sweep is not None and sweep._worker is not None)
                or (experiments is not None and experiments._process is not None))

    scenarios = [("idle (baseline: nothing running)", []), ("render (city, live worker)", [start_render]), ("exposure sweep", [start_sweep]),
                 ("experiment process", [start_experiment]),
                 ("render + sweep + experiment", [start_render, start_sweep, start_experiment])]
    for name, starts in scenarios:
        _wait(app, lambda: False, 0.5)      # settle: work left from before is not this scenario's stall
        ticks.start()
        t0 = time.perf_counter()
        for s in starts:
            s()
        if starts:
            _wait(app, lambda: not busy(), 600)
        else:
            _wait(app, lambda: False, 3.0)
        stats = ticks.stop()
        rows.append({"measure": f"GUI tick gaps during {name}", **stats, "goal_max_gap_ms": 100,
                     "job_s": round(time.perf_counter() - t0, 2)})
    if sweep is None or experiments is None:
        notes.append("sweep or experiments panel missing: their scenarios ran without them")

    # -- a camera move: the low-sample preview, then the refined frame -------------------------
    rows.extend(camera_moves(app, win, 2 if quick else 3))

    # -- Undo of the last move: every stage from the cache --------------------------------------
    undo_stalls = []
    ticks.start()
    shown = win.previews.frames_shown
    t0 = time.perf_counter()
    win.document.undo_stack.undo()
    _wait(app, lambda: win.previews.frames_shown > shown and _full_frame(win), 600)
    undo_stalls.append(ticks.stop()["max_gap_ms"])
    rows.append(_latency_row("edit→pane, Undo of a camera move (city)", [1e3 * (time.perf_counter() - t0)],
                             undo_stalls, 100))

    # -- a CFA edit on the city: a sensor-stage run on the cached render ----------------------
    cfa_stalls = []
    cfa = edit_latency_ms(app, win, "sensor", [{"cfa_pattern": p} for p in (["RGGB", "GRBG"] * n)[:n]],
                          stalls=cfa_stalls)
    rows.append(_latency_row(f"edit→pane, CFA edit on the city, {size[1]}×{size[0]}", cfa, cfa_stalls, 80))

    # -- colour by class on and off ------------------------------------------------------------
    toggles = []
    for on in (True, False, True, False):
        ticks.start()
        t0 = time.perf_counter()
        win.city_view.by_class.setChecked(on)
        _wait(app, lambda: False, 0.3)
        toggles.append((1e3 * (time.perf_counter() - t0), ticks.stop()["max_gap_ms"]))
    rows.append({"measure": "3-D view: Colour by class switched", "max_stall_ms": max(g for _, g in toggles),
                 "goal_stall_ms": 100, "runs": len(toggles)})

    full = load_project("city_paper_camera")
    win.resize(1280, 800)                    # the 3-D view at the size a user sees it, in front
    win.docks["3-D city"].raise_()
    win.apply_edit("city", full.city.model_dump())
    _wait(app, lambda: win.city_view.city is not None and win.city_view._city_key[0] == (full.city, win.document.project.seed), 300)
    win.live.cancel()
    for mouse, name in ((True, "3-D view orbit by mouse drag, full city"),
                        (False, "3-D view turned at full size (no drag), full city")):
        fps = orbit_fps(app, win.city_view, 30 if quick else 120, mouse=mouse)
        rows.append({"measure": name, "fps": round(fps, 1), "goal_fps": 20 if mouse else None,
                     "objects": len(win.city_view.city.objects),
                     "view_px": f"{win.city_view.view.width()}×{win.city_view.view.height()}"})
    win.document.undo_stack.setClean()
    win.close()
    app.processEvents()

    # -- camera moves on a 640×480 city (the size), refined at a few spp ----------------
    big = load_project("city_paper_camera")
    big = big.updated(sensor=big.sensor.updated(rows=480, cols=640), render=big.render.updated(spp=4))
    win = _window(big)
    if not _wait(app, lambda: win.city_view.city is not None and _full_frame(win), 600):
        raise TimeoutError("the 640×480 city's first frame did not arrive")
    rows.extend(camera_moves(app, win, 3 if quick else 5))
    win.document.undo_stack.setClean()
    win.close()
    app.processEvents()
    notes.append(f"city render for the stall test: {size[1]}×{size[0]}, spp {city.render.spp}; "
                 f"timer interval {TICK_MS} ms; Qt platform {app.platformName()}; the 3-D view renders off "
                 "screen on its own thread")
    return {"rows": rows, "notes": notes}


def main(argv: list[str] | None = None) -> int:
    """Run the measurements (on a private Xvfb when there is no display); print them as one JSON line."""
    import argparse
    import json
    import os
    parser = argparse.ArgumentParser(description="window responsiveness (used by `workbench bench gui`)")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--load", type=int, default=0, help="busy processes during the measurement")
    args = parser.parse_args(argv)
    os.environ.setdefault("WORKBENCH_GUI_HOME", tempfile.mkdtemp(prefix="workbench-gui-home-"))  # fresh layout
    from workbench.gui.display import virtual_display
    with virtual_display():
        out = run(quick=args.quick, load=args.load)
        import shiboken6
        from PySide6.QtWidgets import QApplication
        shiboken6.delete(QApplication.instance())       # leave the X server before it stops
    print(json_text(out, indent=None))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
