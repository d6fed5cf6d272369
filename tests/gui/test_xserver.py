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
