"""The parameter models: immutable, finite, strictly typed numbers, a description on every field,
and every sample project still loads."""
import math
from pathlib import Path

import pytest
from pydantic import BaseModel, ValidationError

from workbench.isp.params import ISPParams
from workbench.optics.params import OpticsParams
from workbench.project import PROJECTS_DIR, ExperimentParams, Project, load_project
from workbench.render.params import RenderParams
from workbench.scene.city.recipe import CityRecipe, PoseParams
from workbench.scene.params import SceneParams
from workbench.sensor.params import SensorParams

SECTIONS = (OpticsParams, SceneParams, RenderParams, CityRecipe, PoseParams, SensorParams, ISPParams,
            ExperimentParams)


def _models(cls, seen=None):
    """cls and every parameter model nested in its fields."""
    seen = seen if seen is not None else []
    if cls not in seen:
        seen.append(cls)
        for f in cls.model_fields.values():
            for t in (f.annotation, *getattr(f.annotation, "__args__", ())):
                if isinstance(t, type) and issubclass(t, BaseModel):
                    _models(t, seen)
    return seen


@pytest.mark.parametrize("section", SECTIONS, ids=lambda c: c.__name__)
def test_every_field_has_a_description(section):
    missing = [f"{m.__name__}.{name}" for m in _models(section)
               for name, f in m.model_fields.items() if not (f.description or "").strip()]
    assert not missing


def test_parameters_are_immutable_and_edited_by_copy():
    optics = OpticsParams()
    with pytest.raises(ValidationError, match="frozen"):
        optics.f_number = 2.0
    edited = optics.updated(f_number=2.0)
    assert (optics.f_number, edited.f_number) == (4.0, 2.0)
    assert hash(edited) != hash(optics)             # frozen models key caches


@pytest.mark.parametrize("make", [
    lambda v: OpticsParams(f_number=v), lambda v: OpticsParams(focus_distance_m=v),
    lambda v: SceneParams(distance_m=v), lambda v: SensorParams(exposure_s=v),
    lambda v: SensorParams(read_noise_V=v), lambda v: RenderParams(spp=None, target_rel_error=v),
    lambda v: OpticsParams(distortion_k=(v,)), lambda v: ExperimentParams(ev_biases=[0.0, v])])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_numbers_are_refused(make, value):
    with pytest.raises(ValidationError, match="finite"):
        make(value)


@pytest.mark.parametrize("field, value", [("rows", True), ("rows", "120"), ("exposure_s", "0.01"),
                                          ("pixel_pitch_um", "3"), ("rows", 120.5)])
def test_numbers_are_not_coerced_from_bools_or_strings(field, value):
    with pytest.raises(ValidationError):
        SensorParams(**{field: value})


def test_json_arrays_load_into_tuple_fields():
    pose = PoseParams.model_validate({"pan_range_deg": [-5, 5], "manual_position_xy_m": [1.0, 2.0],
                                      "mode": "manual"})
    assert pose.pan_range_deg == (-5.0, 5.0) and pose.manual_position_xy_m == (1.0, 2.0)
    assert OpticsParams.model_validate({"distortion_k": [0.1]}).distortion_k == (0.1,)
    assert ISPParams.model_validate({"manual_gains": [1, 2, 3]}).manual_gains == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("path", sorted(PROJECTS_DIR.glob("*.json")), ids=lambda p: Path(p).stem)
def test_every_sample_project_loads_and_round_trips(path):
    project = load_project(path)
    assert Project.model_validate_json(project.model_dump_json()) == project
