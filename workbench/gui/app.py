"""The application: `workbench gui [PROJECT]` and the `workbench-gui` script call main(argv)."""
from __future__ import annotations

import os

# Cap OpenMP/BLAS pools before numpy/torch load them (effective when the window is started as
# `workbench-gui` or `python -m workbench.gui.app`): on a 2-core machine a background run must leave
# a core to the GUI thread. The live worker also caps torch and Dr.Jit itself (live.py).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402

DEFAULT_PROJECT = "paper_camera"


def create_window(project_path: str | None = None, with_city_view: bool = True):
    """The main window on a project file or sample name (default: the paper's camera)."""
    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.project import PROJECTS_DIR, load_project, resolve_project_path
    path = resolve_project_path(project_path or DEFAULT_PROJECT)
    sample = path.resolve().parent == PROJECTS_DIR.resolve()      # a sample is never overwritten
    doc = Document(load_project(path), None if sample else path)
    return MainWindow(doc, with_city_view=with_city_view)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="workbench-gui", description="the Camera Workbench window")
    parser.add_argument("project", nargs="?", default=None,
                        help="project file or sample name (default: the welcome page's choice)")
    parser.add_argument("--no-welcome", action="store_true",
                        help=f"skip the welcome page and open {DEFAULT_PROJECT}")
    args = parser.parse_args(argv)
    from PySide6.QtWidgets import QApplication
    app = QApplication.instance() or QApplication([sys.argv[0]])
    app.setApplicationName("Camera Workbench")
    app.setOrganizationName("camera-workbench")
    from workbench.gui.gc_thread import GuiThreadGarbageCollection
    with GuiThreadGarbageCollection():          # before any worker thread starts
        return _run_window(app, args)


def _run_window(app, args) -> int:
    project = args.project
    if project is None and not args.no_welcome:
        project = choose_start_project()
        if project is None:                 # the welcome page was cancelled: no window
            return 0
    window = create_window(project)
    from workbench.gui.crash import install_crash_handler
    install_crash_handler(window)
    window.show()
    from workbench.gui import side_process
    side_process.warm(window.document.project)      # the Metrics dock's first measurement, ahead of time
    window.offer_recovery()
    report_missing_backends(window)
    return app.exec()


def choose_start_project() -> str | None:
    """The welcome page (samples, recent files): the chosen project, or None when it is cancelled."""
    from PySide6.QtCore import QSettings

    from workbench.gui.paths import settings_file
    from workbench.gui.welcome import WelcomeDialog
    recent = QSettings(str(settings_file()), QSettings.Format.IniFormat).value("recent/files") or []
    dialog = WelcomeDialog([recent] if isinstance(recent, str) else list(recent))
    dialog.exec()
    return dialog.choice


def report_missing_backends(window) -> None:
    """Say in the status bar which optional back-ends are missing and what to install."""
    from workbench.diagnostics import check_environment
    missing = [c for c in check_environment() if not c.ok and "optional" not in c.detail]
    if missing:
        window.statusBar().showMessage("; ".join(f"{c.name}: {c.detail}" for c in missing), 30_000)


if __name__ == "__main__":
    sys.exit(main())
