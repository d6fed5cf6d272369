"""Module-level caches stay bounded over a session of focus edits (each edit prepares a new lens)."""
import numpy as np

from workbench.optics.formation import lens_setup, selector
from workbench.optics.lens import pupil_bins
from workbench.optics.params import OpticsParams
from workbench.scene.charts import CHARTS

LENS = "automotive.2.4mm"


def test_200_focus_edits_keep_the_lens_camera_caches_bounded(mi):
    from workbench.render.lens_camera import lens_sensor_dict, plugin
    params = OpticsParams(model="raytrace", lens_file=LENS)
    to_world = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])
    keys = []
    for i in range(200):
        lens, _ = lens_setup.focused_lens(params, 1.0 + 0.05 * i)
        keys.append(lens_sensor_dict(lens, {"width": 4, "height": 3}, to_world, 0.1, n_bins=2)["lens_key"])
    assert len(set(keys)) == 200                               # every edit was a new camera
    assert len(plugin._LENSES) == len(plugin._KEYS) == plugin.CAMERA_CACHE_SIZE
    assert keys[-1] in plugin._LENSES and keys[0] not in plugin._LENSES    # the oldest went first
    assert pupil_bins._pupil_bins.cache_info().currsize <= pupil_bins.BOX_CACHE_SIZE


def test_the_level_selection_cache_keeps_the_latest(monkeypatch):
    monkeypatch.setattr(selector, "CACHE_SIZE", 3)
    monkeypatch.setattr(selector, "_CACHE", type(selector._CACHE)())
    scene = CHARTS["slanted_edge"](size=(24, 32), fov_deg=5.0, distance_m=10.0,
                                   wavelengths_nm=np.array([450.0, 550.0, 650.0]))
    picks = []
    for focus_m in (5.0, 6.0, 7.0, 8.0, 9.0, 10.0):
        picks.append(selector.select_level(scene, OpticsParams(model="auto", focus_distance_m=focus_m)))
    assert len(selector._CACHE) == 3
    again = selector.select_level(scene, OpticsParams(model="auto", focus_distance_m=10.0))
    assert again[1] is picks[-1][1]                            # the same report: served from the cache
