"""A matplotlib Figure in a Qt widget, for the analysis charts (not the live image panes)."""
from __future__ import annotations

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure


class ChartCanvas(FigureCanvasQTAgg):
    """FigureCanvasQTAgg owning its Figure; `redraw(draw)` clears the figure, calls draw(fig), draws."""

    def __init__(self, parent=None, figsize=(5.0, 3.0)):
        super().__init__(Figure(figsize=figsize, layout="constrained"))
        self.setParent(parent)
        self.setMinimumSize(240, 160)

    def redraw(self, draw) -> None:
        self.figure.clear()
        draw(self.figure)
        self.draw_idle()

    def set_figure(self, fig: Figure) -> None:
        """Show a Figure built elsewhere (e.g. on a worker thread), sized to this widget."""
        ratio = self.device_pixel_ratio
        fig.set_dpi(self.figure.dpi)
        fig.set_size_inches(self.width() * ratio / fig.dpi, self.height() * ratio / fig.dpi, forward=False)
        self.figure = fig
        fig.set_canvas(self)
        self.draw_idle()
