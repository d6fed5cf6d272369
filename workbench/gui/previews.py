"""The four live preview panes: irradiance, raw, linear, sRGB (pyqtgraph ImageItem + histogram).

The panes share one zoom/pan (linked view boxes) and fit their image (on the first frame, on every
resize, and on View ▸ Fit) until the user zooms or pans; View ▸ 1:1 shows one image pixel per
screen pixel, zoom in / out step by √2; each pane's right-click menu has these and "Save image…"
(the pane's array as a PNG at full resolution). A pixel inspector under each pane shows the value
and unit under the cursor (irradiance integrated over wavelength in photons/s/m², or at one band in
photons/s/m²/nm; DN and
the pixel's CFA colour for raw, channel values for linear and sRGB); clipped pixels (raw at the
largest code) can be highlighted in red on the raw, linear and sRGB panes. The images are painted
as soon as a frame arrives; the histograms follow HISTOGRAM_DELAY_MS after the last frame, one
pane at a time.
"""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QMetaObject, Qt, QTimer, Signal
from PySide6.QtWidgets import (QCheckBox, QComboBox, QGridLayout, QHBoxLayout, QLabel, QSizePolicy, QVBoxLayout,
                               QWidget)

pg.setConfigOptions(imageAxisOrder="row-major", antialias=False)

PANES = ("irradiance", "raw", "linear", "srgb")


def integrated_irradiance_text(spectrum, wavelengths_nm, sensor_channels: bool = False) -> str:
    """'∫E dλ (400–700 nm) = … photons/s/m²' on a regular wavelength grid (Σ E·Δλ); on the
    channels of a sensor film (sensor_channels), which are no grid, the mean per channel in
    photons/s/m²/nm."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    spectrum = np.asarray(spectrum, dtype=np.float64)
    steps = np.diff(wl)
    if not sensor_channels and wl.size >= 2 and np.allclose(steps, steps[0], rtol=1e-6) and steps[0] > 0:
        return (f"∫E dλ ({wl[0]:g}–{wl[-1]:g} nm) = {float(spectrum.sum() * steps[0]):.4g} photons/s/m² "
                f"({wl.size} bands × {steps[0]:g} nm)")
    return f"mean E over {wl.size} channels = {float(spectrum.mean()):.4g} photons/s/m²/nm"
TITLES = {"irradiance": "Irradiance (sensor plane)", "raw": "Raw (mosaic, DN)",
          "linear": "Linear (demosaiced)", "srgb": "sRGB (full ISP)"}
CLIP_RGBA = (255, 0, 0, 200)
# The histograms follow the images this long after the newest frame (restarted by each frame), so
# the new pixels are painted first and a burst of edits recomputes each histogram once.
HISTOGRAM_DELAY_MS = 60
HISTOGRAM_STEP_MS = 10    # then one pane's histogram at a time, this far apart


@contextmanager
def painted_together(parts):
    """Changes made inside the block to these (pane, graphics item) parts are painted in one
    repaint of the window, and only where the items lie. Left alone, each pane's scene repaints and
    flushes the whole window on its own (QGraphicsView dispatches its update at once; each flush of
    a 1600×1000 window costs a few ms), and re-enabling a view's updates would repaint all of it
    (image, histogram, axes)."""
    from PySide6.QtWidgets import QGraphicsView
    views = {id(pane): pane.view_widget for pane, _item in parts}
    modes = {key: view.viewportUpdateMode() for key, view in views.items()}
    for view in views.values():
        view.setViewportUpdateMode(QGraphicsView.ViewportUpdateMode.NoViewportUpdate)
    try:
        yield
        for view in views.values():             # the scenes' queued updates, now, while the views ignore them
            QMetaObject.invokeMethod(view.scene(), "_q_processDirtyItems", Qt.ConnectionType.DirectConnection)
    finally:
        for key, view in views.items():
            view.setViewportUpdateMode(modes[key])
        for pane, item in parts:                # repainted together by the next event loop pass
            view = pane.view_widget
            view.viewport().update(view.mapFromScene(item.sceneBoundingRect()).boundingRect())


class PaneImage(pg.ImageItem):
    """An ImageItem that draws the 8-bit copy made with its image (display8.Display8) instead of
    rescaling the image on the GUI thread, while the levels are the copy's and no lookup table is
    set (the histogram's gradient or a dragged level region fall back to pyqtgraph's own path)."""

    display8 = None

    def render(self):
        d = self.display8
        levels = self.levels
        if (d is not None and self.lut is None and levels is not None and np.shape(levels) == (2,)
                and (float(levels[0]), float(levels[1])) == d.levels):
            fmt = pg.QtGui.QImage.Format.Format_Grayscale8 if d.u8.ndim == 2 else pg.QtGui.QImage.Format.Format_RGB888
            self.qimage = pg.functions.ndarray_to_qimage(d.u8, fmt)
            self._renderRequired = False
            self._unrenderable = False
            return
        super().render()


class PreviewPane(QWidget):
    """One image with its histogram/levels, title, and inspector line."""

    def __init__(self, name: str, parent=None):
        super().__init__(parent)
        self.name = name
        self.view_widget = pg.GraphicsLayoutWidget()
        self.view_widget.setBackground("k")
        self.view_widget.ci.setContentsMargins(2, 2, 2, 2)
        self.viewbox = self.view_widget.addViewBox(row=0, col=0, lockAspect=True, invertY=True)
        self.viewbox.setMenuEnabled(False)        # our own menu (PreviewPanes.context_menu)
        self.view_widget.sceneObj.contextMenu = []   # no pyqtgraph scene menu either
        self.image = PaneImage()
        self.clip_overlay = pg.ImageItem()
        self.clip_overlay.setZValue(10)
        self.viewbox.addItem(self.image)
        self.viewbox.addItem(self.clip_overlay)
        self.histogram = pg.HistogramLUTItem(image=self.image, fillHistogram=True)
        self.histogram.setMaximumWidth(90)
        self.image.sigImageChanged.disconnect(self.histogram.imageChanged)   # refreshed by refresh_histogram
        self._histogram_stale = False
        self.view_widget.addItem(self.histogram, row=0, col=1)
        self.title = QLabel(f"<b>{TITLES[name]}</b>")
        self.inspector = QLabel("—")
        self.inspector.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        # its text never sets the pane's width (a long line widened the window's minimum from
        # 929 to 1358 px at 1280×800 and made the pane columns unequal): what does not fit is cut,
        # and the whole line is the tooltip
        self.inspector.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.inspector.setMinimumWidth(1)
        top = QHBoxLayout()
        top.addWidget(self.title)
        top.addStretch(1)
        self.band = None
        if name == "irradiance":
            self.band = QComboBox()
            self.band.setToolTip("inspect the irradiance integrated over wavelength, or at one band")
            self.band.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
            top.addWidget(self.band)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        lay.setSpacing(1)
        lay.addLayout(top)
        lay.addWidget(self.view_widget, 1)
        lay.addWidget(self.inspector)
        self._shape: tuple[int, int] | None = None
        self._shown: np.ndarray | None = None

    def set_image(self, array: np.ndarray, levels: tuple[float, float], display=None) -> bool:
        """Show array (the very array already shown, a stage that came from the cache, is
        skipped), drawn from `display` (a display8.Display8 of it) when that is its copy at these
        levels; True when its size differs from the image shown before (or none was)."""
        if array is self._shown:
            return False
        self._shown = array
        new_shape = self._shape != array.shape[:2]
        self._shape = array.shape[:2]
        self.image.display8 = display if display is not None and display.source is array else None
        self.image.setImage(array, autoLevels=False, levels=levels)
        self.histogram.setLevels(*levels)
        self._histogram_stale = True
        return new_shape

    def fit(self) -> None:
        """Show the whole image, as large as the pane allows."""
        if self._shape is not None:
            h, w = self._shape
            self.viewbox.setRange(xRange=(0, w), yRange=(0, h), padding=0)

    def pixels_per_image_pixel(self) -> float:
        """Screen pixels per image pixel at the current zoom (1.0 at 1:1)."""
        (x0, x1), _ = self.viewbox.viewRange()
        return self.viewbox.width() / max(x1 - x0, 1e-9)

    def zoom(self, factor: float) -> None:
        """Zoom about the view's centre by `factor` (> 1: in)."""
        self.viewbox.scaleBy((1.0 / factor, 1.0 / factor))

    def actual_size(self) -> None:
        """One image pixel per screen pixel, about the view's centre."""
        self.zoom(1.0 / self.pixels_per_image_pixel())

    def save_png(self, path: str) -> None:
        """The pane's image array (not a screenshot) as a PNG: 8-bit, levels as shown."""
        from PIL import Image
        data = np.asarray(self._shown)
        lo, hi = self.image.levels if self.image.levels is not None else (0.0, 1.0)
        scaled = np.clip((data.astype(np.float64) - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
        Image.fromarray(np.round(255 * scaled).astype(np.uint8)).save(path)

    def refresh_histogram(self) -> None:
        """Recompute the histogram of the image shown, if it changed since the last refresh."""
        if self._histogram_stale:
            self._histogram_stale = False
            self.histogram.imageChanged()

    def set_clip_mask(self, mask: np.ndarray | None) -> None:
        if mask is None or not mask.any():
            if self.clip_overlay.image is not None:     # clear() re-lays the view out: only when shown
                self.clip_overlay.clear()
            return
        rgba = np.zeros(mask.shape + (4,), np.uint8)
        rgba[mask] = CLIP_RGBA
        self.clip_overlay.setImage(rgba, autoLevels=False, levels=(0, 255))


class PreviewPanes(QWidget):
    """The four panes in a 2×2 grid with shared zoom/pan; show_frame(frame) updates them."""

    inspected = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.panes = {name: PreviewPane(name) for name in PANES}
        grid = QGridLayout()
        grid.setContentsMargins(0, 0, 0, 0)
        for i, name in enumerate(PANES):
            grid.addWidget(self.panes[name], i // 2, i % 2)
        first = self.panes[PANES[0]].viewbox
        for name in PANES[1:]:
            self.panes[name].viewbox.setXLink(first)
            self.panes[name].viewbox.setYLink(first)
        self.fitting = True                       # fit on resize until the user zooms or pans
        for name, pane in self.panes.items():
            pane.viewbox.sigRangeChangedManually.connect(self._user_moved_view)
            pane.viewbox.sigResized.connect(self._pane_resized)
            pane.view_widget.setContextMenuPolicy(Qt.ContextMenuPolicy.CustomContextMenu)
            pane.view_widget.customContextMenuRequested.connect(
                lambda pos, n=name: self.context_menu(n).exec(self.panes[n].view_widget.mapToGlobal(pos)))
        self.highlight_clipped = QCheckBox("Highlight clipped pixels")
        self.highlight_clipped.setToolTip("raw pixels at the largest code, in red")
        self.highlight_clipped.toggled.connect(self._update_clip)
        bar = QHBoxLayout()
        bar.addWidget(self.highlight_clipped)
        bar.addStretch(1)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addLayout(bar)
        lay.addLayout(grid, 1)
        self.frame = None
        self.frames_shown = 0
        for name, pane in self.panes.items():
            pane.view_widget.scene().sigMouseMoved.connect(lambda pos, n=name: self._mouse_moved(n, pos))
        self.panes["irradiance"].band.currentIndexChanged.connect(lambda _i: self._refresh_inspectors())
        self._last_px: tuple[int, int] | None = None
        self._histogram_timer = QTimer(self)
        self._histogram_timer.setSingleShot(True)
        self._histogram_timer.setInterval(HISTOGRAM_DELAY_MS)
        self._histogram_timer.timeout.connect(self._histogram_timer_fired)
        self._histograms_held = False

    # -- zoom ------------------------------------------------------------------------------
    def _user_moved_view(self, *_args) -> None:
        self.fitting = False

    def _pane_resized(self, *_args) -> None:
        if self.fitting:
            self._fit_linked()

    def _fit_linked(self) -> None:
        """Fit the image in every pane: the linked views follow the pane that needs the widest
        range, so no pane crops its image."""
        panes = [p for p in self.panes.values() if p._shape is not None and p.viewbox.width() > 0]
        if panes:
            min(panes, key=lambda p: p.viewbox.width() / max(p.viewbox.height(), 1)).fit()

    def fit(self) -> None:
        """View ▸ Fit: the whole image in every pane, and again after every resize."""
        self.fitting = True
        self._fit_linked()

    def actual_size(self) -> None:
        """View ▸ 1:1: one image pixel per screen pixel (the view stops following resizes)."""
        self.fitting = False
        self.panes[PANES[0]].actual_size()

    def zoom(self, factor: float) -> None:
        """View ▸ Zoom in / out by `factor` about the centre (the view stops following resizes)."""
        self.fitting = False
        self.panes[PANES[0]].zoom(factor)

    def context_menu(self, name: str):
        """A pane's right-click menu: fit, 1:1, zoom, and saving its image."""
        from PySide6.QtWidgets import QMenu
        menu = QMenu(self)
        menu.addAction("Fit", self.fit)
        menu.addAction("1:1 (actual pixels)", self.actual_size)
        menu.addAction("Zoom in", lambda: self.zoom(2 ** 0.5))
        menu.addAction("Zoom out", lambda: self.zoom(2 ** -0.5))
        menu.addSeparator()
        save = menu.addAction(f"Save {TITLES[name].split(' (')[0].lower()} image…", lambda: self.save_dialog(name))
        save.setEnabled(self.panes[name]._shown is not None)
        return menu

    def save_dialog(self, name: str) -> None:
        from PySide6.QtWidgets import QFileDialog
        path, _ = QFileDialog.getSaveFileName(self, "Save image", f"{name}.png", "PNG image (*.png)")
        if path:
            self.panes[name].save_png(path)

    # -- images ----------------------------------------------------------------------------
    def show_frame(self, frame) -> None:
        """Show a live.Frame (numpy arrays) in the four panes; the panes whose image changed are
        painted in one repaint of the window (painted_together)."""
        new_bands = self.frame is None or not np.array_equal(self.frame.wavelengths_nm, frame.wavelengths_nm)
        self.frame = frame
        p = self.panes
        images = {"irradiance": (frame.irradiance_rgb, (0.0, 1.0)), "raw": (frame.raw_dn, (0.0, frame.max_dn)),
                  "linear": (frame.linear_rgb, (0.0, 1.0)), "srgb": (frame.srgb, (0.0, 1.0))}
        changed = [p[name] for name, (array, _levels) in images.items()
                   if array is not p[name]._shown or (name != "irradiance" and self.highlight_clipped.isChecked())]
        with painted_together([(pane, pane.viewbox) for pane in changed]):
            resized = [p[name].set_image(array, levels, frame.display8.get(name))
                       for name, (array, levels) in images.items()]
            self._update_clip()
            if any(resized):                    # a new image size: show it whole
                self.fit()
        if new_bands:
            combo = p["irradiance"].band
            combo.blockSignals(True)
            combo.clear()
            combo.addItem("Σ all bands")
            for wl in frame.wavelengths_nm:
                combo.addItem(f"{wl:g} nm")
            combo.blockSignals(False)
        self._refresh_inspectors()
        self._histogram_timer.start(HISTOGRAM_DELAY_MS)
        self.frames_shown += 1

    def refresh_histograms(self) -> None:
        """Bring every pane's histogram up to the image it shows (normally run by a timer after a
        frame), repainting the window once."""
        stale = [pane for pane in self.panes.values() if pane._histogram_stale]
        with painted_together([(pane, pane.histogram) for pane in stale]):
            for pane in stale:
                pane.refresh_histogram()

    def hold_histograms(self, hold: bool) -> None:
        """While held (a simulation runs), the histograms wait: their timer would otherwise take
        the GUI thread and repaint the window while the next frame is on its way."""
        self._histograms_held = hold
        if not hold and any(pane._histogram_stale for pane in self.panes.values()):
            self._histogram_timer.start(HISTOGRAM_DELAY_MS)

    def _histogram_timer_fired(self) -> None:
        """One pane's histogram a tick (a histogram and its repaint take ~7 ms, four at once
        stalled the GUI 50–90 ms under a CPU hog), the next HISTOGRAM_STEP_MS later."""
        stale = [pane for pane in self.panes.values() if pane._histogram_stale]
        if self._histograms_held or not stale:
            return
        with painted_together([(stale[0], stale[0].histogram)]):
            stale[0].refresh_histogram()
        if len(stale) > 1:
            self._histogram_timer.start(HISTOGRAM_STEP_MS)

    def clipped_mask(self) -> np.ndarray | None:
        if self.frame is None:
            return None
        return self.frame.raw_dn >= self.frame.max_dn

    def _update_clip(self) -> None:
        mask = self.clipped_mask() if self.highlight_clipped.isChecked() else None
        for name in ("raw", "linear", "srgb"):
            self.panes[name].set_clip_mask(mask)

    # -- inspector -------------------------------------------------------------------------
    def _mouse_moved(self, name: str, scene_pos) -> None:
        if self.frame is None:
            return
        pt = self.panes[name].viewbox.mapSceneToView(scene_pos)
        r, c = int(np.floor(pt.y())), int(np.floor(pt.x()))
        h, w = self.frame.raw_dn.shape
        self._last_px = (r, c) if 0 <= r < h and 0 <= c < w else None
        self._refresh_inspectors()

    def _refresh_inspectors(self) -> None:
        texts = self.describe_pixel(self._last_px)
        for name, pane in self.panes.items():
            pane.inspector.setText(texts.get(name, "—"))
            pane.inspector.setToolTip(texts.get(name, ""))
        if self._last_px is not None:
            self.inspected.emit(" | ".join(texts[n] for n in PANES))

    def describe_pixel(self, px: tuple[int, int] | None) -> dict[str, str]:
        """The inspector text of each pane for pixel (row, col) of the current frame."""
        f = self.frame
        if f is None or px is None:
            return {}
        r, c = px
        where = f"({c}, {r})"
        h, w = f.raw_dn.shape
        ih, iw = f.irradiance_photons.shape[:2]
        ir, ic = min(ih - 1, r * ih // h), min(iw - 1, c * iw // w)
        spectrum = f.irradiance_photons[ir, ic]
        band = self.panes["irradiance"].band.currentIndex()
        if band <= 0:
            film = f.project.scene.kind == "city" and f.project.render.representation == "sensor"
            irr = f"{where} {integrated_irradiance_text(spectrum, f.wavelengths_nm, film)}"
        else:
            irr = f"{where} E({f.wavelengths_nm[band - 1]:g} nm) = {float(spectrum[band - 1]):.4g} photons/s/m²/nm"
        th, tw = f.cfa_tile.shape
        colour = f.channel_names[int(f.cfa_tile[r % th, c % tw])]
        dn = float(f.raw_dn[r, c])
        clipped = " (clipped)" if dn >= f.max_dn else ""
        raw = f"{where} {dn:g} DN of {f.max_dn:g}, CFA {colour}{clipped}"
        lin = ", ".join(f"{n} {float(v):.4f}" for n, v in zip(f.channel_names, f.linear[r, c]))
        s = f.srgb[r, c]
        srgb = f"{where} R {s[0]:.3f} G {s[1]:.3f} B {s[2]:.3f} ({', '.join(str(int(round(255 * v))) for v in s)} /255)"
        return {"irradiance": irr, "raw": raw, "linear": f"{where} {lin} (of full scale)", "srgb": srgb}
