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


def test_an_autosave_this_version_cannot_open_is_set_aside_and_reported(qapp, qtbot, tmp_path):
    """A newer version's (or a damaged) autosave used to raise out of the start-up and stay, so
    every later start failed; now it is moved aside once, with a message, and the window opens."""
    import json

    from PySide6.QtWidgets import QMessageBox

    from workbench.gui.document import Document, find_recoverable
    from workbench.gui.main_window import MainWindow
    from workbench.gui.paths import autosave_dir
    from workbench.project import project_to_json
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    folder = autosave_dir()
    folder.mkdir(parents=True, exist_ok=True)
    doc = json.loads(project_to_json(load_project("paper_camera")))
    bad = {"newer": {**doc, "schema_version": 999}, "invalid": {**doc, "sensor": {"rows": -4}}, "none": None}
    for name, project in bad.items():
        autosave = folder / f"session-{name}.json"
        autosave.write_text(json.dumps({"pid": dead.pid, "path": None, "project": project}))
        win = MainWindow(Document(load_project("paper_camera"), None), with_city_view=False)
        win.ask_save_changes = lambda: QMessageBox.StandardButton.Discard
        win.ask_recover = lambda _f: True
        reports = []
        win.report_rejected_autosave = lambda moved, exc: reports.append((moved, str(exc)))
        qtbot.addWidget(win)
        before = win.document.project
        win.offer_recovery()                                  # raised before: the window never started
        assert len(reports) == 1 and reports[0][0] == folder / f"rejected-session-{name}.json"
        assert str(autosave) in reports[0][1] and reports[0][0].exists() and not autosave.exists()
        assert autosave not in find_recoverable() and win.document.project == before
        win.offer_recovery()                                  # never offered again
        assert len(reports) == 1


def test_every_unreadable_autosave_is_moved_aside_with_a_message(qapp, qtbot):
    """Garbage, truncated, empty, a JSON list, a folder and a bad pid: each used to be skipped
    silently and stay; now each is moved aside once, with a message naming it."""
    import json

    from workbench.gui.document import Document, find_recoverable
    from workbench.gui.main_window import MainWindow
    from workbench.gui.paths import autosave_dir
    folder = autosave_dir()
    folder.mkdir(parents=True, exist_ok=True)
    record = json.dumps({"pid": 1, "path": None, "project": None})
    kinds = {"garbage": b"\x00\xffnot json", "truncated": record[:20].encode(), "empty": b"", "list": b"[1, 2]",
             "badpid": json.dumps({"pid": "x", "project": None}).encode(), "nopid": b"{}"}
    for name, data in kinds.items():
        (folder / f"session-{name}.json").write_bytes(data)
    (folder / "session-folder.json").mkdir()
    win = MainWindow(Document(load_project("paper_camera"), None), with_city_view=False)
    qtbot.addWidget(win)
    reports = []
    win.report_rejected_autosave = lambda moved, exc: reports.append((moved, str(exc)))
    win.ask_recover = lambda _f: False
    win.offer_recovery()
    names = sorted([*kinds, "folder"])
    assert sorted(m.name for m, _ in reports) == sorted(f"rejected-session-{n}.json" for n in names)
    for moved, text in reports:
        assert moved.exists() and not (folder / moved.name.removeprefix("rejected-")).exists()
        assert moved.name.removeprefix("rejected-") in text
    assert not find_recoverable()
    win.offer_recovery()                                              # never offered again
    assert len(reports) == len(names)
