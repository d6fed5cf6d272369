"""The optics stage on a scene: the project's optics level on its camera geometry, then the
scene's mean-illuminance adjustment."""
from __future__ import annotations

import dataclasses

import numpy as np

from workbench.errors import StageError
from workbench.optics.formation.geometry import CameraGeometry
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage
from workbench.scene.types import Scene


def scale_to_mean_illuminance(oi: OpticalImage, target_lux: float | None, in_place: bool = False) -> OpticalImage:
    """The optical image scaled to a mean illuminance in lux (scene.adjust_illuminance_lux): a copy,
    or with in_place its own irradiance array scaled (for an array nobody else holds); None
    returns it unchanged."""
    from workbench import spectra
    if target_lux is None:
        return oi
    lux = float(spectra.illuminance_from_photons(
        oi.irradiance_photons.reshape(-1, oi.irradiance_photons.shape[-1]).mean(0), oi.wavelengths_nm))
    if lux <= 0:
        raise StageError("optics", "scene.adjust_illuminance_lux: the optical image is black, it cannot "
                                   "be scaled to a mean illuminance")
    if in_place:
        oi.irradiance_photons *= np.float32(target_lux / lux)
        return oi
    return dataclasses.replace(oi, irradiance_photons=oi.irradiance_photons * np.float32(target_lux / lux))


def form_optical_image(scene: Scene, optics: OpticsParams, camera: CameraGeometry | None,
                       adjust_illuminance_lux: float | None = None) -> OpticalImage:
    """Run the optics level optics.model on `camera` (the geometry the scene was sampled for;
    None: the scene's own field of view), then scale to adjust_illuminance_lux if given."""
    import workbench.optics.formation  # noqa: F401  (registers the optics models)
    from workbench.optics.types import OPTICS_MODELS
    oi = OPTICS_MODELS[optics.model](scene, optics, camera)
    owned = (oi.irradiance_photons.flags.writeable and oi.irradiance_photons.dtype == np.float32
             and not np.may_share_memory(oi.irradiance_photons, scene.radiance_photons))   # a new array
    return scale_to_mean_illuminance(oi, adjust_illuminance_lux, in_place=owned)
