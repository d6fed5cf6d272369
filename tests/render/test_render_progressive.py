"""Progressive rendering: same seed → bit-identical, cancel between chunks, spp from an error target."""
import threading

import numpy as np
import pytest

from workbench.jobs import JobCancelled, run_job
from workbench.render.demo_scene import demo_city, demo_pose
from workbench.render.params import RenderParams
from workbench.render.spectral import render_spectral


class _Flags:
    """A cancel flag whose is_set() answers the given values in turn, then True."""

    def __init__(self, values):
        self.values = iter(values)

    def is_set(self) -> bool:
        return next(self.values, True)


W, H = 32, 24


def run(params, cancel=None, steps=None):
    gen = render_spectral(demo_city(), demo_pose(), params, width=W, height=H, fov_deg=44.0, cancel=cancel)
    return run_job(gen, steps.append if steps is not None else None)


def test_same_seed_is_bit_identical_and_seeds_differ():
    p = RenderParams(spp=6, chunk_spp=2, band_count=4, seed=7)
    a, b = run(p), run(p)
    assert np.array_equal(a.radiance_photons, b.radiance_photons)
    c = run(p.model_copy(update={"seed": 8}))
    assert not np.array_equal(a.radiance_photons, c.radiance_photons)


def test_progress_then_cancel_between_chunks():
    steps, stop = [], threading.Event()

    def on_step(step):
        steps.append(step)
        if len(steps) == 2:
            stop.set()

    gen = render_spectral(demo_city(), demo_pose(), RenderParams(spp=40, chunk_spp=4, preview_spp=1,
                          band_count=4), width=W, height=H, fov_deg=44.0, cancel=stop)
    scene = run_job(gen, on_step)
    assert [s.done for s in steps] == [1, 5]
    assert steps[0].preview.shape == (H, W, 4) and 0 < steps[0].fraction < 1
    assert np.all(np.isfinite(steps[1].preview)) and steps[1].preview.mean() > 0
    assert scene.meta["cancelled"] and scene.meta["spp"] == 5
    assert np.all(np.isfinite(scene.radiance_photons))


def test_cancel_before_start_raises():
    with pytest.raises(JobCancelled):
        run(RenderParams(spp=4, band_count=4), cancel=_Flags([]))


def test_target_error_chooses_spp_from_measured_constant():
    p = RenderParams(spp=None, target_rel_error=0.2, pilot_spp=2, chunk_spp=64, band_count=4)
    steps = []
    scene = run(p, steps=steps)
    c = scene.meta["noise_constant"]
    assert 0.05 < c < 20
    assert scene.meta["spp"] == max(int(np.ceil((c / 0.2) ** 2)), 4)
    assert "pilot" in steps[0].message


def test_cancel_between_pilots_keeps_the_first_pilot():
    p = RenderParams(spp=None, target_rel_error=0.05, pilot_spp=2, band_count=4)
    scene = run(p, cancel=_Flags([False]))
    assert scene.meta["cancelled"] and scene.meta["spp"] == 2 and scene.meta["noise_constant"] is None
