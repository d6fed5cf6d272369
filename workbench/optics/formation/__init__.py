"""Image formation at several levels of detail, one module per level.

Importing this package registers every level in OPTICS_MODELS (workbench.optics.types):
'pinhole', 'diffraction_limited', 'thin_lens', 'psf_grid', 'raytrace' and 'auto' (the
selector, workbench.optics.formation.selector). `radiance_to_irradiance(scene, params, camera)`
runs the level named by params.model on the camera geometry (geometry.CameraGeometry) the scene
was sampled for. The lens-based levels import workbench.optics.lens only when run.
"""
from __future__ import annotations

from workbench.optics.formation import diffraction, pinhole, psf_grid, raytrace, thin_lens  # noqa: F401
from workbench.optics.formation import selector  # noqa: F401  (registers 'auto'; needs the levels above)
from workbench.optics.formation.geometry import CameraGeometry
from workbench.optics.params import OpticsParams
from workbench.optics.types import OPTICS_MODELS, OpticalImage
from workbench.scene.types import Scene


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: CameraGeometry | None = None) -> OpticalImage:
    """Sensor-plane irradiance of `scene` by the optics model `params.model`; `camera`: the
    geometry the scene was sampled for (geometry.scene_geometry when None)."""
    return OPTICS_MODELS[params.model](scene, params, camera)
