"""Claims on jobs that several processes draw from one list: before a process starts a job it
creates `KEY.claim` in a shared folder (O_EXCL: one creator wins) naming its pid and host; others
skip the job while that process lives. A claim whose process is gone (killed, or another sitting's)
is taken over. So any number of processes started on the same experiment share its runs without
training one twice, and a crashed one's run is picked up again."""
from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from workbench.files import pid_alive

SUFFIX = ".claim"


def _held_by_another(path: Path) -> bool:
    """Whether the claim at `path` belongs to another live process (this process's own claim, left by
    a cancelled run, is not another's)."""
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
        pid, host = int(info["pid"]), info["host"]
    except (OSError, ValueError, KeyError, TypeError):
        return False                          # half-written or foreign: treat as stale
    if host != socket.gethostname():
        return True
    return pid != os.getpid() and pid_alive(pid)


def claim(folder: str | os.PathLike, key: str) -> bool:
    """Claim job `key` for this process; False when a live process holds it (another host's claim
    counts as live: its pid cannot be checked from here)."""
    path = Path(folder) / f"{key}{SUFFIX}"
    record = json.dumps({"pid": os.getpid(), "host": socket.gethostname()}).encode()
    for _ in range(2):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            if _held_by_another(path):
                return False
            path.unlink(missing_ok=True)      # stale, or this process's own: take it again
            continue
        with os.fdopen(fd, "wb") as f:
            f.write(record)
        return True
    return False


def release(folder: str | os.PathLike, key: str) -> None:
    """Drop this process's claim on `key` (a no-op when it holds none)."""
    path = Path(folder) / f"{key}{SUFFIX}"
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if info.get("pid") == os.getpid() and info.get("host") == socket.gethostname():
        path.unlink(missing_ok=True)
