"""A thin-lens focus that would blur the scene over several image widths is refused naming the
field, before the FFT grid is allocated (a focus just beyond f once asked for a 98,425² kernel)."""
import pytest

from workbench.errors import ParameterError
from workbench.pipeline import Pipeline
from workbench.project import load_project


def test_a_focus_next_to_the_focal_length_is_refused_by_name():
    p = load_project("paper_camera")
    p = p.updated(sensor=p.sensor.updated(rows=48, cols=64))
    f = p.optics.focal_length_mm * 1e-3
    with pytest.raises(ParameterError, match="optics.focus_distance_m"):
        Pipeline(p.updated(optics=p.optics.updated(model="thin_lens", focus_distance_m=f * 1.00001))).run()
    sharp = Pipeline(p.updated(optics=p.optics.updated(model="thin_lens", focus_distance_m=p.scene.distance_m))).run()
    assert sharp.optical_image.meta["model"] == "thin_lens"
