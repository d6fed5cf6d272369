"""First run and crashes: the welcome page offers the samples; an uncaught exception autosaves the
project first and shows a dialog naming the log file."""
from __future__ import annotations

import sys
import threading

from workbench.project import load_project


def test_welcome_page_lists_every_sample_and_returns_the_pick(qapp, qtbot):
    from workbench.gui.document import sample_projects
    from workbench.gui.welcome import WelcomeDialog
    dialog = WelcomeDialog(["/somewhere/recent.json"])
    qtbot.addWidget(dialog)
    names = [dialog.samples.item(i).text() for i in range(dialog.samples.count())]
    assert names == list(sample_projects()) and "paper_camera" in names
    dialog.samples.setCurrentRow(names.index("paper_camera"))
    dialog.open_button.click()
    assert dialog.choice == "paper_camera"
    assert dialog.recent.item(0).text() == "/somewhere/recent.json"


def test_uncaught_exception_autosaves_then_names_the_log(qapp, qtbot, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.crash import install_crash_handler
    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    monkeypatch.setenv("WORKBENCH_LOG_DIR", str(tmp_path / "logs"))
    project = load_project("paper_camera")
    project = project.updated(sensor=project.sensor.updated(rows=24, cols=32))
    win = MainWindow(Document(project, None), with_city_view=False)
    qtbot.addWidget(win)
    old_hooks = sys.excepthook, threading.excepthook
    try:
        install_crash_handler(win)
        assert win.apply_edit("sensor", {"analog_gain": 2.5})
        try:
            raise RuntimeError("simulated failure in a slot")
        except RuntimeError:
            sys.excepthook(*sys.exc_info())
        qtbot.waitUntil(lambda: getattr(win, "crash_dialog", None) is not None, timeout=5000)
    finally:
        sys.excepthook, threading.excepthook = old_hooks
    text = win.crash_dialog.text()
    assert "simulated failure in a slot" in text
    assert str(win.document.autosave_file) in text and win.document.autosave_file.is_file()
    saved = win.document.autosave_file.read_text()
    assert '"analog_gain": 2.5' in saved
    from workbench.logs import log_path
    assert str(log_path()) in text
    win.crash_dialog.close()
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.close()
