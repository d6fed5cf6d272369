"""GUI tests run on a real X server (Xvfb via Qt's xcb platform), so windows, docks and mouse
events behave as on a desktop. (The 3-D view draws off screen on its own and also works on Qt's
offscreen platform: test_vtk_view checks that in a subprocess.)

When there is no DISPLAY, one Xvfb (1280×1024, 24-bit colour so pixel checks see real colours) is
started for the session and stopped at the end. If Xvfb is not installed the tests are skipped
with the reason. QSettings, recent files and autosave go to a temporary folder (WORKBENCH_GUI_HOME).
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.gui)


@pytest.fixture(scope="session")
def xserver():
    """A DISPLAY for the session: the existing one, or a private Xvfb started here."""
    from workbench.errors import WorkbenchError
    from workbench.gui.display import virtual_display
    os.environ.pop("PYVISTA_OFF_SCREEN", None)
    if os.environ.get("QT_QPA_PLATFORM", "xcb") != "xcb":
        os.environ.pop("QT_QPA_PLATFORM")
    with contextlib.ExitStack() as stack:
        try:
            display = stack.enter_context(virtual_display("1280x1024x24"))
        except WorkbenchError as exc:
            pytest.skip(f"GUI tests need an X server: {exc}")
        yield display


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


@pytest.fixture(scope="module", autouse=True)
def gc_on_gui_thread(qapp):
    """As in the app: Python's cyclic collector runs only on the GUI thread (a worker thread that
    collects garbage holding widgets crashes Qt), and runs automatically again after the module."""
    from workbench.gui.gc_thread import GuiThreadGarbageCollection
    with GuiThreadGarbageCollection() as collector:
        yield collector


@pytest.fixture(autouse=True)
def default_layout(gui_home):
    """Every test's window opens in the first-run layout, whatever an earlier test left in front
    (a window opened after a test had left the Metrics dock in front measured the camera for ~4 s
    on a worker that the test then waited for)."""
    from PySide6.QtCore import QSettings
    from workbench.gui.main_window import LAYOUT_KEY
    from workbench.gui.paths import settings_file
    settings = QSettings(str(settings_file()), QSettings.Format.IniFormat)
    for key in (LAYOUT_KEY, "window/geometry"):
        settings.remove(key)
    settings.sync()


@pytest.fixture(autouse=True)
def no_worker_outlives_its_test(qtbot):
    """Background workers of a test finish, and deliver their results, before its widgets go."""
    yield
    from superqt.utils._qthreading import WorkerBase
    WorkerBase.await_workers(msecs=120_000)
    qtbot.wait(10)


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


@pytest.fixture
def shown(qtbot):
    """shown(widget, width, height) → the widget, owned by the test, at that size and on screen."""
    def show(widget, width: int, height: int):
        qtbot.addWidget(widget)
        widget.resize(width, height)
        widget.show()
        qtbot.waitExposed(widget)
        return widget
    return show
