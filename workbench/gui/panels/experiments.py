"""Experiments panel: runs `workbench experiment isp|exposure|budget PROJECT --data DIR --profile P --out DIR`
as a background process (progress parsed from its output, Cancel kills the process tree) and shows
result folders — its own or ones produced headless elsewhere — as the paper's charts beside the
paired differences that decide them (workbench.experiments.results)."""
from __future__ import annotations

import functools
import os
import re
import sys
import tempfile
from pathlib import Path

import psutil
from PySide6.QtCore import QProcess, QProcessEnvironment, Qt, QTimer, Signal
from PySide6.QtWidgets import (QComboBox, QFileDialog, QGridLayout, QHBoxLayout, QLabel, QLineEdit,
                               QPlainTextEdit, QProgressBar, QPushButton, QSplitter, QVBoxLayout, QWidget)

from workbench.errors import WorkbenchError
from workbench.experiments.detection import PROFILES
from workbench.experiments.results import KINDS, draw_results, read_results, result_folders
from workbench.gui.mplcanvas import BackgroundChart
from workbench.project import save_project

_COUNT = re.compile(r"(\d+)\s*/\s*(\d+)")
KILL_GRACE_MS = 3000
EXPERIMENT_NICE = 10     # the experiment process yields the cores to the window's threads, as the
# render worker and the window's side process do (under a CPU hog: GUI gaps 9–35 → 8–18 ms while one ran)
LOG_LINES = 500


def parse_progress(text: str) -> tuple[int, int] | None:
    """(done, total) from the last 'done/total' in a chunk of the command's output (its progress
    bar writes e.g. 'isp:  33%|███  | 3/9 [00:05<00:10]'), or None."""
    last = None
    for m in _COUNT.finditer(text):
        done, total = int(m.group(1)), int(m.group(2))
        if 0 < total and done <= total:
            last = (done, total)
    return last


def terminate_tree(pid: int) -> list:
    """Send SIGTERM to a process and all its descendants; returns them (for kill_survivors)."""
    try:
        root = psutil.Process(pid)
        procs = root.children(recursive=True) + [root]
    except psutil.NoSuchProcess:
        return []
    for p in procs:
        try:
            p.terminate()
        except psutil.NoSuchProcess:
            pass
    return procs


def kill_survivors(procs: list) -> None:
    """SIGKILL whatever of `procs` is still running (after terminate_tree's grace time)."""
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                p.kill()
        except psutil.NoSuchProcess:
            pass


def _lower_priority(pid: int) -> None:
    """Raise the niceness of a just-started process by EXPERIMENT_NICE (it has no threads or
    children yet to miss it: they inherit it). Not where the platform has no nice."""
    if not pid or not hasattr(os, "setpriority"):
        return
    try:
        os.setpriority(os.PRIO_PROCESS, pid, min(19, os.getpriority(os.PRIO_PROCESS, pid) + EXPERIMENT_NICE))
    except OSError:                       # it has already ended
        pass


class ExperimentsPanel(QWidget):
    """run_finished(int exit code) / run_cancelled() when the process ends; results_shown(dict)
    whenever a results document is drawn. `edited` belongs to the editors' common interface; this
    panel changes no project field, so it never emits it."""

    edited = Signal(str, dict)
    run_finished = Signal(int)
    run_cancelled = Signal()
    results_shown = Signal(dict)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._project = None
        self._project_file: str | None = None
        self._process: QProcess | None = None
        self._cancelled = False
        self._partial = ""                          # output after the last line end
        self._out_dir: Path | None = None
        self.doc: dict | None = None

        self.kind = QComboBox(self)
        self.kind.addItems(KINDS)
        self.kind.setToolTip("isp: raw / linear / sRGB (the paper's Fig. 5); exposure: mAP against EV (Fig. 7); "
                             "budget: is the training budget enough (B against 2B epochs)")
        self.profile = QComboBox(self)
        self.profile.addItems(list(PROFILES))
        self.profile.setCurrentText("standard")
        self.profile.setToolTip("\n".join(p.note for p in PROFILES.values()))
        self.data_dir = QLineEdit(self)
        self.data_dir.setPlaceholderText("rendered data set folder (`workbench dataset`)")
        self.out_dir = QLineEdit(self)
        self.out_dir.setPlaceholderText("output folder (a rerun resumes)")
        browse_data = QPushButton("…", self)
        browse_data.clicked.connect(lambda: self._browse(self.data_dir))
        browse_out = QPushButton("…", self)
        browse_out.clicked.connect(lambda: self._browse(self.out_dir))
        for b in (browse_data, browse_out):
            b.setFixedWidth(32)
        self.run_button = QPushButton("Run experiment", self)
        self.run_button.clicked.connect(self.run_experiment)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.cancel)
        self.open_button = QPushButton("Open result folder…", self)
        self.open_button.clicked.connect(self._open_dialog)
        self.progress = QProgressBar(self)
        self.status = QLabel("open a result folder, or run an experiment", self)
        self.status.setWordWrap(True)
        self.log = QPlainTextEdit(self)
        self.log.setReadOnly(True)
        self.log.setMaximumBlockCount(LOG_LINES)
        self.chart = BackgroundChart("the results' charts appear here", self)

        grid = QGridLayout()
        grid.addWidget(QLabel("Experiment", self), 0, 0)
        grid.addWidget(self.kind, 0, 1)
        grid.addWidget(QLabel("Profile", self), 0, 2)
        grid.addWidget(self.profile, 0, 3)
        grid.addWidget(QLabel("Data", self), 1, 0)
        grid.addWidget(self.data_dir, 1, 1, 1, 3)
        grid.addWidget(browse_data, 1, 4)
        grid.addWidget(QLabel("Output", self), 2, 0)
        grid.addWidget(self.out_dir, 2, 1, 1, 3)
        grid.addWidget(browse_out, 2, 4)
        grid.setColumnStretch(1, 1)
        grid.setColumnStretch(3, 1)
        buttons = QHBoxLayout()
        for w in (self.run_button, self.cancel_button, self.open_button):
            buttons.addWidget(w)
        buttons.addWidget(self.progress, 1)
        split = QSplitter(Qt.Orientation.Vertical, self)
        split.addWidget(self.chart)
        split.addWidget(self.log)
        split.setStretchFactor(0, 4)
        split.setStretchFactor(1, 1)
        lay = QVBoxLayout(self)
        lay.addLayout(grid)
        lay.addLayout(buttons)
        lay.addWidget(self.status)
        lay.addWidget(split, 1)
        self._update_buttons()

    # ------------------------------------------------------------------------------ inputs
    def set_project(self, project) -> None:
        """The project an experiment runs on (its sensor, ISP and EV list); emits nothing."""
        self._project = project
        self._update_buttons()

    def _browse(self, edit: QLineEdit) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Choose a folder", edit.text() or os.getcwd())
        if folder:
            edit.setText(folder)

    def _open_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open result folder", self.out_dir.text() or os.getcwd())
        if folder:
            self.open_folder(folder)

    def open_folder(self, folder: str | Path) -> bool:
        """Draw the results of `folder` (or of the first result folder below it); False + a
        message in the status line if there are none."""
        found = result_folders(folder)
        try:
            doc = read_results(found[0] if found else folder)
        except WorkbenchError as exc:
            self.status.setText(str(exc))
            return False
        self.show_results(doc, found[0] if found else Path(folder))
        return True

    def show_results(self, doc: dict, folder: Path) -> None:
        self.doc = doc
        if self._process is None:
            self.kind.setCurrentText(doc["kind"])
        self.chart.set_draw(functools.partial(draw_results, doc=doc), "drawing the results…")
        runs = len(doc.get("runs", []))
        self.status.setText(f"{folder}: {doc['kind']} experiment, {runs} run(s)"
                            f"{'' if doc.get('complete', True) else ', incomplete'}")
        self.results_shown.emit(doc)

    # ------------------------------------------------------------------------------ the process
    def experiment_argv(self, project_file: str) -> list[str]:
        """The command line of the experiment the controls describe."""
        argv = [sys.executable, "-m", "workbench.cli", "experiment", self.kind.currentText(), project_file,
                "--data", self.data_dir.text().strip(), "--profile", self.profile.currentText()]
        if self.out_dir.text().strip():
            argv += ["--out", self.out_dir.text().strip()]
        return argv

    def run_experiment(self) -> None:
        """Save the shown project to a temporary file and start the experiment command on it."""
        if self._project is None:
            return
        if not self.data_dir.text().strip():
            self.status.setText("choose the rendered data set folder first")
            return
        if not self.out_dir.text().strip():
            self.out_dir.setText(str(Path.cwd() / f"experiment-{self.kind.currentText()}-{self.profile.currentText()}"))
        fd, path = tempfile.mkstemp(prefix="workbench-experiment-", suffix=".json")
        os.close(fd)
        save_project(self._project, path)
        self._project_file = path
        self.run_argv(self.experiment_argv(path), self.out_dir.text().strip())

    def run_argv(self, argv: list[str], out_dir: str | Path) -> None:
        """Start any command as the experiment process; its results are read from out_dir."""
        if self._process is not None:
            return
        self._cancelled = False
        self._partial = ""
        self._out_dir = Path(out_dir)
        proc = QProcess(self)
        proc.setProcessChannelMode(QProcess.ProcessChannelMode.MergedChannels)
        env = QProcessEnvironment.systemEnvironment()
        env.insert("PYTHONUNBUFFERED", "1")
        proc.setProcessEnvironment(env)
        proc.readyReadStandardOutput.connect(self._read_output)
        proc.finished.connect(self._finished)
        proc.errorOccurred.connect(self._process_error)
        self._process = proc
        self.progress.setRange(0, 0)             # busy until the first count arrives
        self.log.clear()
        self.log.appendPlainText("$ " + " ".join(argv))
        self.status.setText("running…")
        proc.start(argv[0], argv[1:])
        _lower_priority(proc.processId())
        self._update_buttons()

    def cancel(self) -> None:
        """Stop the experiment process and everything it started (finished runs stay on disk):
        SIGTERM now, SIGKILL to what is left after KILL_GRACE_MS, without blocking the GUI."""
        if self._process is None:
            return
        self._cancelled = True
        pid = self._process.processId()
        if pid:
            procs = terminate_tree(pid)
            QTimer.singleShot(KILL_GRACE_MS, lambda: kill_survivors(procs))

    def shutdown(self) -> None:
        """The window is closing: stop a running experiment (its finished runs are kept)."""
        self.cancel()

    def _read_output(self) -> None:
        self._take_output(bytes(self._process.readAllStandardOutput()).decode("utf-8", errors="replace"))

    def _take_output(self, text: str, final: bool = False) -> None:
        """Whole lines go to the log; a segment ended by a carriage return (a progress bar
        redrawing itself) only moves the progress bar; a partial line waits for the rest."""
        parts = re.split(r"(\r\n|\r|\n)", self._partial + text)
        self._partial = "" if final else parts.pop()
        if final:
            parts += [""] if len(parts) % 2 else []
        counted = None
        for segment, end in zip(parts[0::2], parts[1::2]):
            counted = parse_progress(segment) or counted
            if (end != "\r" or final) and segment.strip():
                self.log.appendPlainText(segment.rstrip())
        if counted is not None:
            self.progress.setRange(0, counted[1])
            self.progress.setValue(counted[0])
            self._refresh_results()

    def _refresh_results(self) -> None:
        if self._out_dir is not None and (self._out_dir / "results.json").is_file():
            try:
                self.show_results(read_results(self._out_dir), self._out_dir)
            except WorkbenchError:
                pass                                # being rewritten; the next count redraws

    def _process_error(self, error) -> None:
        if error == QProcess.ProcessError.FailedToStart:
            self.status.setText(f"could not start the experiment: {self._process.errorString()}")
            self._finished(-1, None)

    def _finished(self, code: int, _status) -> None:
        if self._process is None:
            return
        self._take_output(bytes(self._process.readAllStandardOutput()).decode("utf-8", errors="replace"),
                          final=True)
        self._process.deleteLater()
        self._process = None
        if self._project_file:
            Path(self._project_file).unlink(missing_ok=True)
            self._project_file = None
        self.progress.setRange(0, 1)
        if self._cancelled:
            self.progress.setValue(0)
            self.status.setText("experiment cancelled; finished runs are kept in the output folder "
                                "(run again to resume)")
            self._update_buttons()
            self.run_cancelled.emit()
            return
        self.progress.setValue(1 if code == 0 else 0)
        if code == 0 and self._out_dir is not None:
            self.open_folder(self._out_dir)
        elif code != 0:
            self.status.setText(f"experiment failed (exit code {code}); see the log below")
        self._update_buttons()
        self.run_finished.emit(code)

    def _update_buttons(self) -> None:
        running = self._process is not None
        self.run_button.setEnabled(not running and self._project is not None)
        self.cancel_button.setEnabled(running)

    def closeEvent(self, event) -> None:
        self.shutdown()
        super().closeEvent(event)
