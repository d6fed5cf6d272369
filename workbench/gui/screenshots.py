"""Screenshots for the README (`python -m workbench.gui.screenshots docs/ [--results FOLDER]`):
the default layout at 1280×800 on the paper camera and on the city sample (also with its 3-D view
in front), the main window on the
city sample, the lens editor, the exposure-sweep panel after a sweep, and the experiments panel
on a result folder (alone: --experiments-only). Runs on a private Xvfb when there is no display."""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def _wait(app, predicate, timeout_s: float) -> None:
    from workbench.gui.bench import _wait as wait_in_loop
    if not wait_in_loop(app, predicate, timeout_s):
        raise TimeoutError("the window did not get there in time")


def _settle(app, seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        app.processEvents()
        time.sleep(0.01)


def _save(widget, path: Path) -> Path:
    if not widget.grab().save(str(path)):
        raise OSError(f"could not write {path}")
    print(f"wrote {path}")
    return path


def take(out: Path, results: Path | None, size=(240, 320), metrics_only: bool = False,
         layout_only: bool = False, experiments_only: bool = False) -> list[Path]:
    from PySide6.QtWidgets import QApplication

    import workbench.gui  # noqa: F401
    from workbench.gui.gc_thread import GuiThreadGarbageCollection
    app = QApplication.instance() or QApplication(["workbench-screenshots"])
    with GuiThreadGarbageCollection():
        if metrics_only:
            out.mkdir(parents=True, exist_ok=True)
            return _metrics_shots(app, out)
        if experiments_only:
            if results is None:
                raise ValueError("--experiments-only needs --results FOLDER")
            out.mkdir(parents=True, exist_ok=True)
            return _experiments_only(app, out, results)
        return _take(app, out, results, size, layout_only)


def _take(app, out: Path, results: Path | None, size, layout_only: bool = False) -> list[Path]:
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.project import load_project
    out.mkdir(parents=True, exist_ok=True)
    written = _default_layout(app, load_project("paper_camera"), out / "window-paper-1280x800.png")
    written += _default_layout(app, load_project("city_paper_camera"), out / "window-city-1280x800.png",
                               out / "window-city-3d-1280x800.png")
    if layout_only:
        return written

    city = load_project("city_paper_camera")
    city = city.updated(sensor=city.sensor.updated(rows=size[0], cols=size[1]))
    win = MainWindow(Document(city))
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.resize(1600, 1000)
    win.show()
    win.previews.highlight_clipped.setChecked(False)
    _wait(app, lambda: win.city_view.city is not None and win.previews.frame is not None
          and not win.previews.frame.preview and not win.live.busy, 900)
    win.docks["Sensor"].raise_()
    _settle(app, 1.0)
    _wait(app, win.city_view.view.is_current, 60)       # the 3-D view drawn at its final size
    _settle(app, 1.0)
    written.append(_save(win, out / "window-city.png"))

    lens = win.editors.get("Lens")
    if lens is not None:
        auto = load_project("city_automotive_lens_full_model")
        lens.setParent(None)
        lens.resize(1300, 900)
        lens.set_project(auto)
        lens.show()
        _wait(app, lambda: all(v.is_current() for v in lens.chart_views.values() if v.isVisible()), 300)
        _settle(app, 1.0)
        written.append(_save(lens, out / "lens-editor.png"))

    sweep = win.editors.get("Exposure sweep")
    if sweep is not None:
        sweep.setParent(None)
        sweep.resize(1300, 700)
        sweep.show()
        frame = win.previews.frame
        sweep.set_frame(frame.project, frame.signal_rate_e_per_s, frame.colour_wavelengths_nm)
        done = []
        sweep.sweep_finished.connect(done.append)
        sweep.run()
        _wait(app, lambda: bool(done), 600)
        _settle(app, 1.0)
        written.append(_save(sweep, out / "sweep-panel.png"))

    experiments = None
    if results is not None:
        experiments = win.editors.get("Experiments")
        written.append(_experiments_shot(app, experiments, city, results, out))
    written += _metrics_shots(app, out)
    win.document.undo_stack.setClean()
    win.close()
    for w in (lens, sweep, experiments):
        if w is not None:
            w.close()
    app.processEvents()
    return written


def _experiments_shot(app, experiments, project, results: Path, out: Path) -> Path:
    """The Experiments panel, out of its dock at 1300×800, on the result folder `results`."""
    experiments.setParent(None)
    experiments.resize(1300, 800)
    experiments.show()
    experiments.set_project(project)
    if not experiments.open_folder(results):
        raise FileNotFoundError(f"no experiment results under {results}")
    _wait(app, experiments.chart.is_current, 120)
    _settle(app, 1.0)
    return _save(experiments, out / "experiments-panel.png")


def _experiments_only(app, out: Path, results: Path) -> list[Path]:
    """Only the Experiments panel's screenshot, set to the city sample, in a window on the paper
    camera's charts (no city render)."""
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.project import load_project
    city = load_project("city_paper_camera")
    win = MainWindow(Document(load_project("paper_camera")), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    experiments = win.editors["Experiments"]
    shot = _experiments_shot(app, experiments, city, results, out)
    win.document.undo_stack.setClean()
    win.close()
    experiments.close()
    app.processEvents()
    return [shot]


def _default_layout(app, project, path: Path, city_view_path: Path | None = None) -> list[Path]:
    """The window as it first opens on `project` at 1280×800 (default layout), its full frame shown;
    with city_view_path, also the same window with the 3-D city dock in front (its default view)."""
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    win = MainWindow(Document(project))
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.resize(1280, 800)
    win.show()
    _wait(app, lambda: win.previews.frame is not None and not win.previews.frame.preview and not win.live.busy, 900)
    if win.city_view is not None and win.city_view.view is not None:
        _wait(app, win.city_view.view.is_current, 60)
    _settle(app, 1.5)
    shots = [_save(win, path)]
    if city_view_path is not None:
        win.docks["3-D city"].raise_()
        _settle(app, 1.0)
        _wait(app, win.city_view.view.is_current, 60)       # drawn at the dock's size
        _settle(app, 1.0)
        shots.append(_save(win, city_view_path))
    win.document.undo_stack.setClean()
    win.close()
    app.processEvents()
    return shots


def _metrics_shots(app, out: Path) -> list[Path]:
    """The Metrics dock at its default width in the window at 1280×800, comparing the paper camera
    (pinned as A) with 1.5 µm pixels (B): the window with the table and the MTF chart
    (metrics-ab.png), and the dock alone on the A | B | B − A strip (metrics-panel.png)."""
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.project import load_project
    win = MainWindow(Document(load_project("paper_camera")), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.resize(1280, 800)
    win.show()
    panel = win.editors["Metrics"]
    _settle(app, 0.5)                              # the first-run layout puts the Sensor dock in front
    win.docks["Metrics"].raise_()
    done = []
    panel.measured.connect(done.append)
    for n, edit in enumerate((None, {"pixel_pitch_um": 1.5})):
        if edit is not None:
            win.apply_edit("sensor", edit)
        project = win.document.project
        _wait(app, lambda n=n, p=project: len(done) > n and panel._worker is None and panel._measured == p
              and panel._frame is not None and panel._frame.project == p, 600)
        if n == 0:
            panel.pin()
    _wait(app, lambda: all(v.is_current() for v in panel.chart_views.values() if v.isVisible()), 120)
    _settle(app, 1.0)
    written = [_save(win, out / "metrics-ab.png")]
    panel.charts.setCurrentWidget(panel.ab)
    _wait(app, lambda: panel.ab.pixmap() is not None and not panel.ab.pixmap().isNull() and panel._ab_worker is None,
          60)
    _settle(app, 1.0)
    written.append(_save(win.docks["Metrics"], out / "metrics-panel.png"))
    win.document.undo_stack.setClean()
    win.close()
    app.processEvents()
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out", type=Path, help="folder for the PNG files")
    parser.add_argument("--results", type=Path, default=None, help="an experiment result folder to show")
    parser.add_argument("--metrics-only", action="store_true", help="only the Metrics dock's two screenshots")
    parser.add_argument("--layout-only", action="store_true",
                        help="only the default layouts at 1280×800 (paper camera; city sample, also with its 3-D view)")
    parser.add_argument("--experiments-only", action="store_true",
                        help="only the Experiments panel on --results (no render)")
    args = parser.parse_args(argv)
    if args.experiments_only and args.results is None:
        parser.error("--experiments-only needs --results FOLDER")
    import os
    import tempfile
    os.environ.setdefault("WORKBENCH_GUI_HOME", tempfile.mkdtemp(prefix="workbench-gui-home-"))  # fresh layout
    from workbench.gui.display import virtual_display
    with virtual_display("1700x1100x24"):
        take(args.out, args.results, metrics_only=args.metrics_only, layout_only=args.layout_only,
             experiments_only=args.experiments_only)
        import shiboken6
        from PySide6.QtWidgets import QApplication
        shiboken6.delete(QApplication.instance())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
