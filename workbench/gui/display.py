"""A display for headless runs of the window (benchmarks, screenshots): Xvfb when DISPLAY is unset."""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from workbench.errors import WorkbenchError


def _free_display() -> int:
    for n in range(99, 160):
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
            return n
    raise WorkbenchError("no free X display number between :99 and :159")


def die_with_parent() -> None:
    """preexec_fn for a helper process (Xvfb): Linux sends it SIGTERM when its parent dies, so an
    aborted run leaves no X server behind."""
    import ctypes
    import signal
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
    except OSError:
        pass


@contextlib.contextmanager
def virtual_display(size: str = "1600x1000x24"):
    """Yield the DISPLAY to use: the current one, or a private Xvfb (24-bit) stopped on exit."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise WorkbenchError("no display and no Xvfb: install xvfb or run with a display")
    num = _free_display()
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen([xvfb, f":{num}", "-screen", "0", size, "-nolisten", "tcp"],
                                stdout=log, stderr=subprocess.STDOUT, preexec_fn=die_with_parent)
        deadline = time.monotonic() + 15
        while not Path(f"/tmp/.X11-unix/X{num}").exists():
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                raise WorkbenchError(f"Xvfb :{num} did not start")
            time.sleep(0.05)
        os.environ["DISPLAY"] = f":{num}"
        try:
            yield os.environ["DISPLAY"]
        finally:
            os.environ.pop("DISPLAY", None)
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
