"""Matplotlib charts in Qt widgets (not the live image panes): a live canvas, or an image of a\nchart rendered on a worker thread."""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QLabel


class ChartCanvas(FigureCanvasQTAgg):
    """FigureCanvasQTAgg owning its Figure; `redraw(draw)` clears the figure, calls draw(fig), draws.

    A hidden canvas (a tab not in front) defers the Agg draw to its next paint, so an edit does not
    rasterise charts nobody sees on the GUI thread; `redraw_when_seen(draw)` defers building the
    figure too (clearing and re-plotting axes costs ~30 ms on this machine's GUI thread)."""

    def __init__(self, parent=None, figsize=(5.0, 3.0)):
        super().__init__(Figure(figsize=figsize, layout="constrained"))
        self.setParent(parent)
        self.setMinimumSize(240, 160)
        self._stale = False
        self._pending_draw = None

    def redraw(self, draw) -> None:
        self._pending_draw = None
        self.figure.clear()
        draw(self.figure)
        self._request_draw()

    def redraw_when_seen(self, draw) -> None:
        """redraw(draw) now when the canvas is on screen, else when it is next painted."""
        if self.isVisible():
            self.redraw(draw)
        else:
            self._pending_draw = draw
            self._stale = True

    def set_figure(self, fig: Figure) -> None:
        """Show a Figure built elsewhere (e.g. on a worker thread), sized to this widget."""
        ratio = self.device_pixel_ratio
        fig.set_dpi(self.figure.dpi)
        fig.set_size_inches(self.width() * ratio / fig.dpi, self.height() * ratio / fig.dpi, forward=False)
        self._pending_draw = None
        self.figure = fig
        fig.set_canvas(self)
        self._request_draw()

    def _request_draw(self) -> None:
        if self.isVisible():
            self.draw_idle()
        else:
            self._stale = True

    def paintEvent(self, event) -> None:
        if self._stale:
            self._stale = False
            if self._pending_draw is not None:
                draw, self._pending_draw = self._pending_draw, None
                self.figure.clear()
                draw(self.figure)
            FigureCanvasAgg.draw(self)
        super().paintEvent(event)


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
