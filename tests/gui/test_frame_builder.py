"""FrameBuilder keeps the irradiance pane's image of the last few optical images, so Undo and
Redo (which bring back optical images the stage cache still holds) do not make it again."""
from __future__ import annotations

import numpy as np

from workbench.gui import live
from workbench.pipeline import Pipeline
from workbench.project import load_project


def test_undo_and_redo_reuse_the_irradiance_preview_of_an_optical_image_still_held(monkeypatch):
    import workbench.previews as previews              # FrameBuilder imports it from there when it needs it
    made = []
    original = previews.irradiance_preview

    def counting(photons, wavelengths_nm, meta=None):
        made.append(photons.shape)
        return original(photons, wavelengths_nm, meta)
    monkeypatch.setattr(previews, "irradiance_preview", counting)
    base = load_project("paper_camera")
    a = base.updated(sensor=base.sensor.updated(rows=60, cols=80))
    b = a.updated(optics=a.optics.updated(f_number=8.0))
    pipe = Pipeline(a)
    builder = live.FrameBuilder()
    first = builder.build(pipe, a, preview=False, submitted_at=0.0)
    pipe.set_project(b)
    second = builder.build(pipe, b, preview=False, submitted_at=0.0)
    pipe.set_project(a)                                  # Undo: the stage cache's optical image of a
    undone = builder.build(pipe, a, preview=False, submitted_at=0.0)
    assert len(made) == 2
    assert undone.irradiance_rgb is first.irradiance_rgb and not np.array_equal(first.irradiance_rgb,
                                                                                second.irradiance_rgb)
    for _ in range(live.IRRADIANCE_PREVIEWS + 1):       # more optical images than it keeps: a forgets
        b = b.updated(optics=b.optics.updated(f_number=b.optics.f_number + 1.0))
        pipe.set_project(b)
        builder.build(pipe, b, preview=False, submitted_at=0.0)
    assert len(builder._irr_rgb) == live.IRRADIANCE_PREVIEWS
