"""render_city_frame end to end on the procedural city (tiny): the real renderer, labels and
optics agree on the pixel grid, and a frame is a pure function of (project, frame index)."""
import json

import numpy as np
import pytest

from workbench.project import Project, load_project
from workbench.render.city_frame import frame_optical_image, frame_seeds, render_city_frame
from workbench.scene.city.recipe import CLASS_IDS, CityRecipe, PoseParams


def tiny_city_project(seed=0) -> Project:
    doc = json.loads(load_project("paper_camera").model_dump_json())
    doc["seed"] = seed
    doc["scene"].update(kind="city", adjust_illuminance_lux=None, fov_deg=44.0)
    doc["city"] = CityRecipe(blocks_x=1, blocks_y=1).model_dump()
    doc["pose"] = PoseParams().model_dump()
    doc["sensor"].update(rows=24, cols=32)
    doc["render"].update(spp=1, band_count=4, max_depth=2)
    return Project.model_validate(doc)


@pytest.mark.slow
def test_city_frame_is_reproducible_and_consistent():
    project = tiny_city_project()
    a = render_city_frame(project, frame_seeds(0, 1))
    b = render_city_frame(project, frame_seeds(0, 1))
    assert a.irradiance_photons.shape == (24, 32, 4) and a.labels.shape == (24, 32)
    assert a.irradiance_photons.tobytes() == b.irradiance_photons.tobytes()
    assert a.labels.objects == b.labels.objects
    assert np.isfinite(a.irradiance_photons).all() and a.irradiance_photons.max() > 0
    names = {o.class_name for o in a.labels.objects}
    assert names and names <= set(CLASS_IDS)
    for o in a.labels.objects:               # per-object counts agree with the maps
        assert o.visible_px == np.count_nonzero(a.labels.instance_id == o.instance_id)
        assert o.class_id == CLASS_IDS[o.class_name]
    oi = frame_optical_image(a)
    assert oi.shape == a.labels.shape and oi.sample_spacing_m > 0
    other = render_city_frame(project, frame_seeds(0, 2))
    assert other.meta["pose"] != a.meta["pose"]
