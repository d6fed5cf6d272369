"""The GUI test set-up itself: a real X server with 24-bit colour and Qt on xcb."""
def test_qt_runs_on_xcb_and_grabs_real_pixels(qapp, qtbot, grab):
    from PySide6.QtGui import QColor, QPalette
    from PySide6.QtWidgets import QLabel
    label = QLabel("workbench")
    pal = label.palette()
    pal.setColor(QPalette.ColorRole.Window, QColor(10, 200, 30))
    label.setAutoFillBackground(True)
    label.setPalette(pal)
    label.resize(80, 40)
    qtbot.addWidget(label)
    label.show()
    qtbot.waitExposed(label)
    pixels = grab(label)
    assert qapp.platformName() == "xcb"
    assert tuple(pixels[2, 2]) == (10, 200, 30)      # 24-bit: exact colour comes back


def test_many_void_calls_and_emits_do_not_exhaust_none_or_true(qapp):
    """PySide6 6.12 on CPython 3.11 drops a reference to None per void call and to True per emit;
    workbench.gui guards it (without the guard this aborts the interpreter)."""
    from PySide6.QtCore import QObject, Signal

    class Emitter(QObject):
        ping = Signal(int)

    obj = Emitter()
    obj.ping.connect(lambda _v: None)
    for i in range(200_000):
        obj.setObjectName("x")
        obj.ping.emit(i)
    assert obj.objectName() == "x"
