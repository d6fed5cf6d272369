"""The preview panes draw a frame's 8-bit copies (made by the live worker) instead of rescaling
floats on the GUI thread, and show exactly what pyqtgraph's own rescaling shows; a frame repaints
only the panes' image views, not their histograms."""
from __future__ import annotations

import dataclasses

import numpy as np
import pyqtgraph as pg
import pytest
from PySide6.QtGui import QImage

from workbench.display8 import Display8
from workbench.gui.live import FrameBuilder
from workbench.gui.previews import PaneImage, PreviewPanes
from workbench.pipeline import Pipeline
from workbench.project import load_project


def pixels(qimage: QImage) -> np.ndarray:
    rgb = qimage.convertToFormat(QImage.Format.Format_RGB888)
    h, w, stride = rgb.height(), rgb.width(), rgb.bytesPerLine()
    return np.frombuffer(rgb.constBits(), np.uint8, count=rgb.sizeInBytes()).reshape(h, stride)[:, :3 * w].copy()


def rendered(item, image, levels):
    item.setImage(image, autoLevels=False, levels=levels)
    item.render()
    return pixels(item.qimage)


@pytest.mark.parametrize("shape, levels", [((30, 40, 3), (0.0, 1.0)), ((30, 40), (0.0, 1023.0))])
def test_the_8_bit_copy_draws_the_pixels_pyqtgraph_draws_from_the_floats(qtbot, shape, levels):
    rng = np.random.default_rng(1)
    image = rng.uniform(-0.1, 1.1, size=shape).astype(np.float32) * np.float32(levels[1])
    plain, pane = pg.ImageItem(), PaneImage()
    pane.display8 = Display8.of(image, levels)
    assert np.array_equal(rendered(pane, image, levels), rendered(plain, image, levels))
    assert pane.qimage.constBits() is not None and pane.qimage.width() == shape[1]
    # levels dragged in the histogram: the copy no longer applies; pyqtgraph's own path draws them
    dragged = (0.2 * levels[1], 0.7 * levels[1])
    assert np.array_equal(rendered(pane, image, dragged), rendered(plain, image, dragged))


@pytest.fixture
def panes(shown):
    return shown(PreviewPanes(), 900, 700)


def small_frame():
    base = load_project("paper_camera")
    project = base.updated(sensor=base.sensor.updated(rows=60, cols=80))
    return FrameBuilder().build(Pipeline(project), project, preview=False, submitted_at=0.0)


def test_a_frame_is_drawn_from_its_8_bit_copies_and_repaints_only_the_image_views(panes, qtbot, monkeypatch):
    from PySide6.QtCore import QEvent, QObject, QRect
    frame = small_frame()
    assert set(frame.display8) == {"irradiance", "raw", "linear", "srgb"}
    rescaled = []
    original = pg.functions_qimage.try_make_qimage
    monkeypatch.setattr(pg.functions_qimage, "try_make_qimage",
                        lambda *a, **k: rescaled.append(1) or original(*a, **k))
    panes.show_frame(frame)
    qtbot.wait(200)                                           # painted, histograms refreshed
    assert rescaled == []
    assert all(pane.image.qimage is not None for pane in panes.panes.values())

    class Regions(QObject):
        def __init__(self):
            super().__init__()
            self.painted = QRect()

        def eventFilter(self, obj, event):
            if event.type() == QEvent.Type.Paint:
                self.painted = self.painted.united(event.rect())
            return False
    srgb = panes.panes["srgb"]
    regions = Regions()
    srgb.view_widget.viewport().installEventFilter(regions)
    panes.show_frame(dataclasses.replace(frame, srgb=1.0 - frame.srgb))   # no copy for this array: floats
    qtbot.wait(30)                                            # before the histogram timer
    srgb.view_widget.viewport().removeEventFilter(regions)
    histogram = srgb.view_widget.mapFromScene(srgb.histogram.sceneBoundingRect()).boundingRect()
    assert not regions.painted.isEmpty() and not regions.painted.intersects(histogram)
    assert rescaled                                           # the replaced image went pyqtgraph's way
