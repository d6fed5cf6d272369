"""Autosave and recovery: unsaved edits of a session that is killed come back in the next one."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from workbench.project import load_project, save_project

CHILD = textwrap.dedent("""
    import sys
    import workbench.gui
    from PySide6.QtWidgets import QApplication
    from workbench.gui.document import Document
    from workbench.gui.main_window import MainWindow
    from workbench.project import load_project
    app = QApplication(["child"])
    path = sys.argv[1]
    win = MainWindow(Document(load_project(path), path, autosave_interval_ms=100), with_city_view=False)
    win.show()
    assert win.apply_edit("sensor", {"analog_gain": 3.0})
    assert win.apply_edit("isp", {"illuminant_correction": "white_world"})
    def report():
        if win.document.autosave_file.exists():
            print("AUTOSAVED", win.document.autosave_file, flush=True)
            timer.stop()
    from PySide6.QtCore import QTimer
    timer = QTimer(); timer.timeout.connect(report); timer.start(50)
    app.exec()
""")


def test_unsaved_edits_come_back_after_the_process_is_killed(qapp, qtbot, tmp_path):
    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document, find_recoverable
    from workbench.gui.main_window import MainWindow
    original = load_project("paper_camera")
    original = original.updated(sensor=original.sensor.updated(rows=24, cols=32))
    path = tmp_path / "project.json"
    save_project(original, path)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        line = ""
        while not line.startswith("AUTOSAVED"):
            line = child.stdout.readline()
            assert line, "the child ended before autosaving"
        autosave = Path(line.split(maxsplit=1)[1].strip())
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(10)
    assert autosave in find_recoverable()
    win = MainWindow(Document(original, path), with_city_view=False)
    win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
    win.ask_recover = lambda _f: True
    qtbot.addWidget(win)
    win.offer_recovery()
    project = win.document.project
    assert project.sensor.analog_gain == 3.0 and project.isp.illuminant_correction == "white_world"
    assert project == original.updated(sensor=original.sensor.updated(analog_gain=3.0),
                                       isp=original.isp.updated(illuminant_correction="white_world"))
    assert win.document.dirty and win.document.path == path
    assert not autosave.exists() and autosave not in find_recoverable()
    win.document.undo_stack.undo()                  # the recovered edits are one undoable step
    assert win.document.project == original
    assert load_project(path) == original           # the file itself was never touched
