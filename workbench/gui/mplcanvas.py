"""Matplotlib charts in Qt widgets (not the live image panes), drawn and rasterised off the GUI
thread: the GUI thread only shows the pixels (an Agg draw of one chart took 0.13–0.6 s here)."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QLabel, QSizePolicy
from superqt.utils import create_worker

RESIZE_REDRAW_MS = 250    # a resized chart is drawn again at its new size this long after the last resize


def render_rgba(draw, width_px: int, height_px: int, dpi: float = 100.0) -> np.ndarray:
    """draw(fig) on a fresh Agg figure of width_px×height_px → H×W×4 uint8 (safe on a worker thread:
    no pyplot, no Qt; metrics.charts.chart_rgba)."""
    from workbench.metrics.charts import chart_rgba
    return chart_rgba(draw, width_px, height_px, dpi)


class ChartImage(QLabel):
    """A chart rasterised elsewhere (render_rgba on a worker), so the GUI thread only blits pixels;
    shows a hint text until the first chart arrives."""

    def __init__(self, hint: str, parent=None):
        super().__init__(hint, parent)
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setWordWrap(True)
        self.setMinimumSize(240, 160)
        self.setStyleSheet("background: white; color: #666;")

    def size_px(self) -> tuple[int, int]:
        """The device-pixel size to render the next chart at."""
        ratio = self.devicePixelRatioF()
        return round(max(self.width(), 240) * ratio), round(max(self.height(), 160) * ratio)

    def show_rgba(self, rgba: np.ndarray) -> None:
        rgba = np.ascontiguousarray(rgba)
        h, w, _ = rgba.shape
        pixmap = QPixmap.fromImage(QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy())
        pixmap.setDevicePixelRatio(self.devicePixelRatioF())
        self.setPixmap(pixmap)


class BackgroundChart(ChartImage):
    """A chart drawn by draw(fig) at the widget's size in the window's side process, shown as an
    image: matplotlib's Python (an Agg draw took 0.13–0.6 s here; a lens chart's first view stalled
    the window up to 0.8 s) never holds the window's GIL. draw must pickle: a Qt-free module-level function or a functools.partial of one.

    set_draw(draw) draws when the chart is on screen — at once, or when it is next shown (a tab
    not in front costs nothing) — and again after a resize; one job at a time, the newest draw
    wins. drawn() is emitted when the image of the newest draw is shown."""

    drawn = Signal()

    def __init__(self, hint: str, parent=None):
        super().__init__(hint, parent)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)   # not the pixmap's size
        self._draw = None
        self._shown = None            # (draw, size in px) of the image shown
        self._worker = None
        self._resized = QTimer(self)
        self._resized.setSingleShot(True)
        self._resized.setInterval(RESIZE_REDRAW_MS)
        self._resized.timeout.connect(self._start)

    def set_draw(self, draw, hint: str | None = None) -> None:
        """Show draw(fig) from now on; `hint` is the text shown until its image arrives when no
        image is shown yet."""
        self._draw = draw
        if hint is not None and self.pixmap().isNull():
            self.setText(hint)
        self._start()

    def set_image(self, draw, rgba: np.ndarray) -> None:
        """Show `rgba`, an image of draw(fig) made elsewhere (e.g. in a process) at this chart's
        size_px(); a later resize draws it again here."""
        self._draw = draw
        self._shown = (draw, (rgba.shape[1], rgba.shape[0]))
        self.show_rgba(rgba)
        self.drawn.emit()
        self._start()                         # resized since the image was asked for

    def figure(self, dpi: float = 100.0) -> Figure:
        """A Figure drawn by the current draw on this thread at the size it is shown at (as
        chart_rgba draws it), laid out, to inspect what the chart shows and where."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        width_px, height_px = self.size_px()
        fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi, layout="constrained")
        if self._draw is not None:
            self._draw(fig)
        FigureCanvasAgg(fig).draw()
        return fig

    def is_current(self) -> bool:
        """Whether the image shown is the newest draw's, at the widget's size."""
        return self._draw is not None and self._shown == (self._draw, self.size_px())

    def showEvent(self, event) -> None:
        super().showEvent(event)
        self._start()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if self._draw is not None:
            self._resized.start()

    def _start(self) -> None:
        if self._draw is None or not self.isVisible() or self._worker is not None or self.is_current():
            return
        job = (self._draw, self.size_px())
        from workbench.gui import side_process
        from workbench.metrics.charts import chart_rgba
        self._worker = create_worker(side_process.run, chart_rgba, job[0], *job[1], _start_thread=False,
                                     _ignore_errors=True)
        self._worker.returned.connect(lambda rgba: self._returned(job, rgba))
        self._worker.errored.connect(lambda exc: self._errored(job, exc))
        self._worker.finished.connect(self._finished)
        self._worker.start()

    def _returned(self, job, rgba: np.ndarray) -> None:
        self._shown = job
        self.show_rgba(rgba)
        if job[0] is self._draw:
            self.drawn.emit()

    def _errored(self, job, exc: Exception) -> None:
        self._shown = job                     # not tried again until the draw or the size changes
        self.setText(f"chart failed: {exc}")

    def _finished(self) -> None:
        self._worker = None
        self._start()                         # a newer draw or size arrived meanwhile
