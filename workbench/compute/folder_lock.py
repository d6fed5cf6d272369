"""An exclusive lock on an output folder, so two runs never write the same folder at once.

The lock is an flock on `.workbench.lock` in the folder: the kernel drops it when the holder exits,
however it exits (kill -9 included), so a stale lock never blocks a rerun. The file names the holder
(pid, host, command) for the error a second run gets."""
from __future__ import annotations

import fcntl
import json
import os
import socket
import time
from contextlib import contextmanager
from pathlib import Path

from workbench.errors import OutputPathError

LOCK_NAME = ".workbench.lock"


def hold_file_lock(path: str | os.PathLike, what: str):
    """The lock of one output file (a contact sheet, a claims report): `.NAME.lock` beside it, so
    two commands writing one file are refused while others may write beside it."""
    path = Path(path)
    return hold_folder_lock(path.parent, what, lock_name=f".{path.name}.lock")


@contextmanager
def hold_folder_lock(folder: str | os.PathLike, what: str, wait: bool = False, lock_name: str = LOCK_NAME):
    """Hold the folder's lock for the body; OutputPathError naming the holder if another has it
    (wait=True: wait until it is free instead, for short turns such as a merge of records)."""
    path = Path(folder) / lock_name
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise OutputPathError(folder, f"cannot make its lock file ({exc.strerror or exc})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputPathError(folder, f"is in use by {_holder(fd)}; wait for it to finish or stop "
                                          "it (its finished work is kept)") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "what": what,
                                  "since_unix_s": round(time.time())}).encode(), 0)
        yield
    finally:
        os.close(fd)                      # closing drops the flock


def _holder(fd: int) -> str:
    """Who holds the lock, from what it wrote into the lock file."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        return f"{info.get('what', 'another run')} (pid {info['pid']} on {info.get('host', '?')})"
    except (ValueError, KeyError, OSError, UnicodeDecodeError):
        return "another run"
