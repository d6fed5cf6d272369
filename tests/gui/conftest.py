"""GUI tests run on a real X server (Xvfb + Mesa via Qt's xcb platform), never Qt's offscreen
platform (no OpenGL there, so the 3-D view would be blank) and never PYVISTA_OFF_SCREEN (the
embedded interactor would grab black). See shared research note gui.md §1.

When there is no DISPLAY, one Xvfb (1280×1024, 24-bit colour so pixel checks see real colours) is
started for the session and stopped at the end. If Xvfb is not installed the tests are skipped
with the reason. QSettings, recent files and autosave go to a temporary folder (WORKBENCH_GUI_HOME).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.gui)


def _die_with_parent() -> None:
    """Xvfb gets SIGTERM when the test process dies (an aborted run leaves no X server behind)."""
    import ctypes
    import signal
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
    except OSError:
        pass


def _free_display() -> int:
    for n in range(99, 160):
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
            return n
    raise RuntimeError("no free X display number between :99 and :159")


@pytest.fixture(scope="session")
def xserver(tmp_path_factory):
    """A DISPLAY for the session: the existing one, or a private Xvfb started here."""
    os.environ.pop("PYVISTA_OFF_SCREEN", None)
    if os.environ.get("QT_QPA_PLATFORM", "xcb") != "xcb":
        os.environ.pop("QT_QPA_PLATFORM")
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("GUI tests need an X server: no DISPLAY and Xvfb is not installed "
                    "(apt-get install xvfb)")
    num = _free_display()
    log = tmp_path_factory.mktemp("xvfb") / "xvfb.log"
    with open(log, "w") as fh:
        proc = subprocess.Popen([xvfb, f":{num}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
                                stdout=fh, stderr=subprocess.STDOUT, preexec_fn=_die_with_parent)
    socket = Path(f"/tmp/.X11-unix/X{num}")
    deadline = time.monotonic() + 15
    while not socket.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.skip(f"Xvfb :{num} did not start: {log.read_text()[-400:]}")
        time.sleep(0.05)
    os.environ["DISPLAY"] = f":{num}"
    try:
        yield os.environ["DISPLAY"]
    finally:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
        os.environ.pop("DISPLAY", None)


@pytest.fixture(scope="session")
def gui_home(tmp_path_factory):
    """Settings, recent files and autosave of the GUI go here, not to the user's folders."""
    home = tmp_path_factory.mktemp("gui-home")
    os.environ["WORKBENCH_GUI_HOME"] = str(home)
    return home


@pytest.fixture(scope="session")
def qapp_args():
    return ["workbench-tests", "-platform", "xcb"]


@pytest.fixture(scope="session")
def qapp(xserver, gui_home, qapp_args):
    """pytest-qt's QApplication, created only once the X server is up (xcb platform)."""
    import workbench.gui  # noqa: F401  (guards the PySide6 6.12 refcount bug before Qt is used)
    from PySide6.QtWidgets import QApplication
    app = QApplication.instance() or QApplication(qapp_args)
    if app.platformName() != "xcb":
        pytest.skip(f"GUI tests need Qt's xcb platform on an X server, got '{app.platformName()}'")
    yield app


def grab_array(widget):
    """The widget's on-screen pixels as an H×W×3 uint8 array (QWidget.grab)."""
    import numpy as np
    from PySide6.QtGui import QImage
    img = widget.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    h, w, bpl = img.height(), img.width(), img.bytesPerLine()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=h * bpl).reshape(h, bpl)
    return buf[:, : w * 3].reshape(h, w, 3).copy()


@pytest.fixture
def grab():
    """grab(widget) → the widget's pixels as an H×W×3 uint8 array."""
    return grab_array
