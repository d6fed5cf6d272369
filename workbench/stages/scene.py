"""The scene stage for analytic charts: the project's chart sampled on its camera geometry."""
from __future__ import annotations

import inspect

from workbench.optics.formation.geometry import CameraGeometry
from workbench.scene import charts
from workbench.scene.params import SceneParams
from workbench.scene.types import Scene

# Chart keyword → the scene field that gives it (a chart takes the ones its signature names).
CHART_OPTION_FIELDS = {"illuminant": "illuminant", "mean_luminance_cd_m2": "mean_luminance_cd_m2",
                       "angle_deg": "edge_angle_deg", "contrast": "edge_contrast",
                       "exit_luminance_cd_m2": "hdr_exit_luminance_cd_m2",
                       "tunnel_luminance_cd_m2": "hdr_tunnel_luminance_cd_m2"}


def chart_scene(params: SceneParams, camera: CameraGeometry) -> Scene:
    """The chart params.kind (a charts.CHARTS entry; 'city' is rendered, not drawn) on
    camera.shape samples over camera.hfov_deg."""
    draw = charts.CHARTS[params.kind]
    accepted = inspect.signature(draw).parameters
    options = {name: getattr(params, field) for name, field in CHART_OPTION_FIELDS.items() if name in accepted}
    return draw(size=camera.shape, fov_deg=camera.hfov_deg, distance_m=params.distance_m,
                wavelengths_nm=params.wavelengths.grid(), **options)
