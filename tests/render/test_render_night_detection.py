"""The night samples of the detection experiments (issue 33 item 5): city_detection_night (RGGB)
and city_detection_night_rccc are city_detection_quick's cities, poses and render settings at
night through an automotive night camera that differs between them only in its filters; both
render at a tiny size, and a data set renders from each and feeds the detection loader."""
import json

import numpy as np
import pytest

from workbench.project import load_project

NIGHT = ("city_detection_night", "city_detection_night_rccc")


def test_the_night_samples_are_the_dense_city_at_night():
    from workbench.stages.geometry import project_geometry
    quick = load_project("city_detection_quick")
    bayer, rccc = (load_project(n) for n in NIGHT)
    for p in (bayer, rccc):
        assert p.render.world.lighting == "night" and p.render.world.night.vehicle_lights
        assert (p.seed, p.city, p.pose, p.experiment) == (quick.seed, quick.city, quick.pose, quick.experiment)
        # the day set's sampler and film; one chunk of 100 spp (RGGB) or 144 (RCCC: its clear pixels take ~3x the
        # electrons, so the same render noise is larger against their shot noise), where each meets the criterion
        assert p.render.updated(world=quick.render.world, spp=quick.render.spp, chunk_spp=quick.render.chunk_spp,
                                preview_spp=quick.render.preview_spp) == quick.render
        assert p.render.spp == p.render.chunk_spp == p.render.preview_spp
        assert p.render.world.night.light_selection == "shading"
        assert (p.sensor.rows, p.sensor.cols) == (240, 320)
        assert project_geometry(p).hfov_deg == pytest.approx(project_geometry(quick).hfov_deg, abs=0.01)
        assert p.sensor.max_exposure_s == pytest.approx(1 / 30) and p.optics.f_number == 2.0
    assert (bayer.render.spp, rccc.render.spp) == (100, 144)          # squares: the multijitter sampler keeps them
    assert (bayer.sensor.cfa_pattern, rccc.sensor.cfa_pattern) == ("RGGB", "RCCC")
    assert bayer.sensor.ir_cut_file is not None and rccc.sensor.ir_cut_file is None
    assert bayer.sensor.updated(cfa_pattern="RCCC", ir_cut_file=None) == rccc.sensor   # only the filters differ


@pytest.mark.parametrize("name", NIGHT)
def test_the_night_samples_render_through_their_camera_at_a_tiny_size(mi, name):
    from workbench.datasets.contact_sheet import camera_tile, sheet_project
    project = sheet_project(load_project(name), 32, 24, 4)
    tile = camera_tile(project, 0)
    r = tile.record
    assert r["lighting"] == "night: hps lamps, vehicle lights"
    assert r["cfa"] == load_project(name).sensor.cfa_pattern
    assert 0 < r["exposure_s"] <= 1 / 30 + 1e-9
    assert tile.srgb.shape == (24, 32, 3) and np.isfinite(tile.srgb).all() and tile.srgb.max() > 0


@pytest.mark.slow
@pytest.mark.parametrize("name", NIGHT)
def test_a_data_set_renders_from_each_night_sample_and_feeds_the_loader(mi, tmp_path, name):
    from workbench.cli import main
    from workbench.datasets.contact_sheet import sheet_project
    from workbench.datasets.dataset import SPEC_NAME
    from workbench.detect.data import DetectionDataset, DetectionView
    from workbench.project import save_project
    small = sheet_project(load_project(name), 32, 24, 4)
    path = tmp_path / f"{name}.json"
    save_project(small, path)
    out = tmp_path / "set"
    assert main(["dataset", str(path), "--frames", "2", "--out", str(out), "--workers", "0"]) == 0
    spec = json.loads((out / SPEC_NAME).read_text())
    assert spec["project"]["name"] == name and spec["project"]["render"]["world"]["lighting"] == "night"
    assert main(["dataset-verify", str(out)]) == 0
    data = DetectionDataset(out)
    assert len(data.frames) == 2 and data.project.sensor.cfa_pattern == small.sensor.cfa_pattern
    for representation in ("raw", "srgb"):
        x, target = DetectionView(data, [0, 1], representation)[0]
        assert x.shape[-2:] in ((24, 32), (12, 16)) and bool(np.isfinite(x.numpy()).all())   # raw: packed 2×2
        assert 0 < target["exposure_s"] <= 1 / 30 + 1e-9


@pytest.mark.parametrize("name", ["budget-standard", "isp-standard", "schedule-study/budget-batch16"])
def test_the_committed_results_data_set_is_still_the_one_city_detection_quick_makes(name):
    """Adding the night samples and the tunnel's luminaire length leaves city_detection_quick's
    data-set fingerprint the one the committed result folders were measured on."""
    from pathlib import Path

    from workbench.datasets.dataset import dataset_fingerprint
    from workbench.render.city_frame import render_city_frame
    folder = Path(__file__).resolve().parents[2] / "docs" / "results" / name
    recorded = json.loads((folder / "results.json").read_text())["dataset"]["fingerprint"]
    assert dataset_fingerprint(load_project("city_detection_quick"), "float16", render_city_frame) == recorded


def test_night_data_sets_made_before_the_lamp_fix_are_not_resumed():
    """Night frames made while the street lamps sat inside the pavement cannot be mixed with new
    ones: a night project's fingerprint carries NIGHT_LIGHTS_VERSION (a day project's does not,
    above)."""
    from unittest import mock

    from workbench.datasets import dataset
    from workbench.render.city_frame import render_city_frame
    night = load_project("city_detection_night")
    now = dataset.dataset_fingerprint(night, "float16", render_city_frame)
    with mock.patch.object(dataset, "NIGHT_LIGHTS_VERSION", 1):
        assert dataset.dataset_fingerprint(night, "float16", render_city_frame) != now


def test_tunnel_sets_made_before_the_tunnel_fixes_are_not_resumed():
    """A project with a tunnel, by day or night, carries TUNNEL_VERSION (its frames changed with the
    underlay, roulette and coat fixes); tunnel-less projects do not read it."""
    from unittest import mock

    from workbench.datasets import dataset
    from workbench.render.city_frame import render_city_frame
    projects = {name: load_project(name) for name in ("city_tunnel", "city_detection_quick", "city_detection_night")}
    projects["city_tunnel night"] = projects["city_tunnel"].updated(render=projects["city_tunnel"].render.updated(
        world=projects["city_tunnel"].render.world.updated(lighting="night")))
    now = {k: dataset.dataset_fingerprint(p, "float16", render_city_frame) for k, p in projects.items()}
    with mock.patch.object(dataset, "TUNNEL_VERSION", 0):
        then = {k: dataset.dataset_fingerprint(p, "float16", render_city_frame) for k, p in projects.items()}
    assert [k for k in now if now[k] != then[k]] == ["city_tunnel", "city_tunnel night"]
