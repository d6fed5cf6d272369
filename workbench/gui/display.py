"""A display for headless runs of the window (benchmarks, screenshots): Xvfb when DISPLAY is unset."""
from __future__ import annotations

import contextlib
import os
import select
import shutil
import subprocess
import tempfile
import time

from workbench.errors import WorkbenchError


XVFB_START_S = 15.0      # how long Xvfb may take to accept connections


def _read_display_number(fd: int, proc: subprocess.Popen, timeout_s: float) -> int:
    """The display number Xvfb writes to its -displayfd pipe once it accepts connections."""
    text = b""
    deadline = time.monotonic() + timeout_s
    while not text.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            raise WorkbenchError(f"Xvfb did not start within {timeout_s:.0f} s")
        chunk = os.read(fd, 16)
        if not chunk:
            raise WorkbenchError(f"Xvfb closed its display pipe (exit code {proc.poll()}) before it took a display")
        text += chunk
    return int(text)


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
    read_fd, write_fd = os.pipe()
    with tempfile.TemporaryFile() as log:
        # -displayfd: Xvfb itself takes a free display number (atomically, by its lock file), so two
        # runs starting at once cannot share one server; it writes the number when it is ready.
        proc = subprocess.Popen([xvfb, "-displayfd", str(write_fd), "-screen", "0", size, "-nolisten", "tcp"],
                                stdout=log, stderr=subprocess.STDOUT, pass_fds=(write_fd,),
                                preexec_fn=die_with_parent)
        os.close(write_fd)
        try:
            num = _read_display_number(read_fd, proc, XVFB_START_S)
        except WorkbenchError as exc:
            proc.kill()
            log.seek(0)
            raise WorkbenchError(f"{exc}: {log.read()[-400:].decode(errors='replace')}") from None
        finally:
            os.close(read_fd)
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
