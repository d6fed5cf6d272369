"""The workbench's log: a rotating file in the platform's user log folder (platformdirs).

The command line and the window both call setup_logging() once; a one-line error shown to the
user has its full traceback here. WORKBENCH_LOG_DIR overrides the folder (tests, frozen apps).
"""
from __future__ import annotations

import logging
import logging.handlers
import os
from pathlib import Path

APP_NAME = "camera-workbench"
LOG_FILE_NAME = "workbench.log"
MAX_LOG_BYTES = 2_000_000
LOG_BACKUPS = 3


def log_dir() -> Path:
    """The folder of the log file (created if needed)."""
    override = os.environ.get("WORKBENCH_LOG_DIR")
    if override:
        folder = Path(override)
    else:
        from platformdirs import user_log_dir
        folder = Path(user_log_dir(APP_NAME, appauthor=False))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def log_path() -> Path:
    return log_dir() / LOG_FILE_NAME


def setup_logging(level: int = logging.INFO) -> Path | None:
    """Send the 'workbench' loggers to the rotating log file; return its path (None if unwritable)."""
    root = logging.getLogger("workbench")
    for handler in root.handlers:
        if isinstance(handler, logging.handlers.RotatingFileHandler):
            return Path(handler.baseFilename)
    try:
        path = log_path()
        handler = logging.handlers.RotatingFileHandler(path, maxBytes=MAX_LOG_BYTES,
                                                       backupCount=LOG_BACKUPS, encoding="utf-8")
    except OSError:
        return None                    # a read-only home must not stop the program
    handler.setFormatter(logging.Formatter("%(asctime)s %(process)d %(levelname)s %(name)s: %(message)s"))
    root.addHandler(handler)
    root.setLevel(level)
    return path
