"""Scene section of the project: which analytic chart or city, its light and sampling."""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from workbench.errors import InvalidValueError
from workbench import spectra
from workbench.params import Params


class WavelengthParams(Params):
    """Wavelength sampling (nm), both ends included. 400–700 nm in 10 nm steps by default."""

    start_nm: float = Field(400.0, ge=300.0, le=1100.0, description="first wavelength (nm); chart scenes")
    stop_nm: float = Field(700.0, ge=300.0, le=1100.0, description="last wavelength (nm); chart scenes")
    step_nm: float = Field(10.0, gt=0.0, le=200.0, description="wavelength step (nm); chart scenes")

    @model_validator(mode="after")
    def _ordered(self):
        if self.stop_nm < self.start_nm:
            raise InvalidValueError(f"stop_nm ({self.stop_nm}) must be ≥ start_nm ({self.start_nm})")
        if (self.stop_nm - self.start_nm) / self.step_nm > 400:
            raise InvalidValueError("more than 400 wavelength samples; use a larger step_nm")
        return self

    def grid(self) -> np.ndarray:
        return spectra.wavelength_grid(self.start_nm, self.stop_nm, self.step_nm)


VISIBLE_NM = (380.0, 780.0)


class SceneParams(Params):
    """The scene: an analytic chart (uniform, macbeth, slanted_edge, hdr_tunnel) or a city.

    The chart is sampled on the sensor's pixel grid × oversample over the camera's field of view
    unless fov_deg is given. adjust_illuminance_lux rescales the optical image to a mean sensor
    illuminance (the paper's experiments use 1000 lux); None keeps the absolute radiometry."""

    kind: Literal["uniform", "macbeth", "slanted_edge", "hdr_tunnel", "city"] = Field(
        "macbeth", description="an analytic chart (scene.charts.CHARTS) or 'city' (rendered by Mitsuba); scene stage")
    illuminant: str = Field("D65", description="illuminant name (spectra.illuminant_spd: D65, A, blackbody:T…); "
                                               "uniform, macbeth, slanted_edge charts")
    mean_luminance_cd_m2: float = Field(100.0, gt=0.0, le=1e9, description="mean scene luminance (cd/m²); uniform, "
                                                                           "macbeth, slanted_edge charts")
    distance_m: float = Field(10.0, gt=0.0, le=1e6, description="chart distance (m), and the focus distance when "
                                                                "optics.focus_distance_m is None; scene stage, optics")
    fov_deg: float | None = Field(None, gt=0.0, lt=180.0,
                                  description="horizontal field of view (deg) the scene spans; None = the sensor "
                                              "behind the optics (the camera geometry); scene stage")
    oversample: int = Field(1, ge=1, le=8, description="scene samples per pixel along each axis (count): the "
                                                       "optical-image spacing is pixel pitch / oversample; scene stage")
    wavelengths: WavelengthParams = Field(WavelengthParams(), description="wavelength sampling (nm) of the charts")
    adjust_illuminance_lux: float | None = Field(None, gt=0.0, le=1e7,
                                                 description="rescale the optical image to this mean sensor "
                                                             "illuminance (lux); None keeps the absolute "
                                                             "radiometry; optics stage")
    edge_angle_deg: float = Field(5.0, ge=-45.0, le=45.0, description="edge tilt from vertical (deg); slanted_edge chart")
    edge_contrast: float = Field(0.8, gt=0.0, le=1.0, description="(bright − dark)/bright (0–1); slanted_edge chart")
    hdr_exit_luminance_cd_m2: float = Field(20000.0, gt=0.0, le=1e9,
                                            description="daylight exit luminance (cd/m²); hdr_tunnel chart")
    hdr_tunnel_luminance_cd_m2: float = Field(0.05, gt=0.0, le=1e6,
                                              description="tunnel wall luminance (cd/m²); hdr_tunnel chart")

    @field_validator("illuminant")
    @classmethod
    def _known_illuminant(cls, value: str) -> str:
        return spectra.checked_illuminant_name(value)      # raises with the allowed names

    @model_validator(mode="after")
    def _visible_wavelengths(self):
        """A chart is scaled to a luminance, which needs a wavelength the eye sees."""
        grid = self.wavelengths.grid()
        lo, hi = VISIBLE_NM
        if self.kind != "city" and not ((grid >= lo) & (grid <= hi)).any():
            raise InvalidValueError(f"scene.wavelengths {grid[0]:g}–{grid[-1]:g} nm: a chart is scaled to its "
                                    f"luminance (cd/m²), so its wavelengths must include one in {lo:g}–{hi:g} nm, "
                                    "where the eye is sensitive")
        return self
