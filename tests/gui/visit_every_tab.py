"""Opens the window on a project, then shows every dock and every tab inside it, one after the
other, with events processed in between (run as a script by test_every_tab.py, so a crash of Qt
fails that test instead of the test process). Prints one 'visited …' line per tab, then 'done'."""
from __future__ import annotations

import faulthandler
import sys

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QTabWidget


def main(project: str, width: int, height: int) -> int:
    faulthandler.enable()
    app = QApplication([sys.argv[0], "-platform", "xcb"])
    from workbench.gui.app import create_window
    from workbench.gui.gc_thread import GuiThreadGarbageCollection
    with GuiThreadGarbageCollection():
        window = create_window(project)
        window.ask_save_changes = lambda: None
        window.resize(width, height)
        window.show()
        steps = []
        for title, dock in window.docks.items():
            steps.append((f"dock {title}", dock.raise_))
            for tabs in dock.widget().findChildren(QTabWidget):
                for i in range(tabs.count()):
                    steps.append((f"dock {title} / tab {tabs.tabText(i)}", lambda t=tabs, i=i: t.setCurrentIndex(i)))

        def run(k: int = 0) -> None:
            if k == len(steps):
                print("done", flush=True)
                app.quit()
                return
            name, show = steps[k]
            show()
            print("visited", name, flush=True)
            QTimer.singleShot(150, lambda: run(k + 1))   # the layout of the shown tab runs first
        QTimer.singleShot(1500, run)
        app.exec()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3])))
