"""Uncaught exceptions in the window: autosave first, log the traceback, tell the user where it is.

install_crash_handler(window) replaces sys.excepthook (and threading.excepthook) while the window
lives. The project is never lost: the document's unsaved edits go to the autosave folder before
the dialog opens, and the next start offers to recover them.
"""
from __future__ import annotations

import logging
import sys
import threading
import traceback

from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import QMessageBox

from workbench.logs import log_path, setup_logging

log = logging.getLogger("workbench.gui.crash")


class _CrashRelay(QObject):
    """Carries an exception from any thread to the GUI thread, where the dialog may open."""

    crashed = Signal(str, str)     # summary, traceback text


def crash_message(summary: str, autosaved: str | None, log_file: str | None) -> str:
    saved = (f"Your unsaved edits were saved to {autosaved}; they are offered back at the next start."
             if autosaved else "There were no unsaved edits.")
    where = f"The details are in the log: {log_file}" if log_file else "The log file could not be written."
    return f"An unexpected error occurred: {summary}\n\n{saved}\n{where}"


def install_crash_handler(window) -> _CrashRelay:
    """Route uncaught exceptions to an autosave + a dialog naming the log file."""
    setup_logging()
    relay = _CrashRelay(window)

    def on_crash(summary: str, text: str) -> None:
        autosaved = None
        try:
            path = window.document.autosave()
            autosaved = str(path) if path else None
        except Exception:                      # noqa: BLE001 — the handler must not raise
            log.exception("autosave after a crash failed")
        try:
            log_file = str(log_path())
        except OSError:
            log_file = None
        box = QMessageBox(QMessageBox.Icon.Critical, "Camera Workbench — error",
                          crash_message(summary, autosaved, log_file), QMessageBox.StandardButton.Ok, window)
        box.setDetailedText(text)
        box.setWindowModality(Qt.WindowModality.WindowModal)
        window.crash_dialog = box
        box.open()

    relay.crashed.connect(on_crash, Qt.ConnectionType.QueuedConnection)

    def report(exc_type, exc, tb) -> None:
        if issubclass(exc_type, KeyboardInterrupt):
            sys.__excepthook__(exc_type, exc, tb)
            return
        text = "".join(traceback.format_exception(exc_type, exc, tb))
        log.error("uncaught exception:\n%s", text)
        relay.crashed.emit(f"{exc_type.__name__}: {exc}", text)

    sys.excepthook = report
    threading.excepthook = lambda args: report(args.exc_type, args.exc_value, args.exc_traceback)
    return relay
