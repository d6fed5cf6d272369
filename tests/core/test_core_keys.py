"""Cache keys and data-set fingerprints (stages.keys.digest) survive a schema that grows: a field
added later with a default gives the same digest for every model that leaves it at the default,
and a different one as soon as it is set; different values never share a digest."""
from pydantic import create_model

from workbench.datasets.dataset import dataset_fingerprint
from workbench.render.city_frame import render_city_frame
from workbench.project import load_project
from workbench.stages.keys import digest


def test_a_new_defaulted_field_keeps_the_old_digest():
    old = create_model("Recipe", x=(float, 1.0), tunnel=(dict | None, None))
    new = create_model("Recipe", x=(float, 1.0), tunnel=(dict | None, None), parked=(int, 0))
    assert digest(old(x=2.0)) == digest(new(x=2.0)) == digest(new(x=2.0, parked=0))
    assert digest(new(x=2.0, parked=3)) != digest(new(x=2.0))
    assert digest(old(x=2.0)) != digest(old()) == digest(old(x=1.0))
    assert digest(old(tunnel={"a": 1})) != digest(old())


def test_the_new_scene_switches_off_keep_a_data_set_fingerprint():
    project = load_project("city_detection_quick")
    base = dataset_fingerprint(project, "float16", render_city_frame)
    assert project.city.n_parked_cars == 0 and project.city.horizon_field_m == 0.0
    on = project.updated(city=project.city.updated(n_parked_cars=4))
    assert dataset_fingerprint(on, "float16", render_city_frame) != base
    back = on.updated(city=on.city.updated(n_parked_cars=0))
    assert dataset_fingerprint(back, "float16", render_city_frame) == base
