"""Parameters of the optics stage (project-file section and GUI form).

Defaults are the seed paper's camera (Table 1): a pinhole with 44° horizontal field of view on
a 640×480 sensor of 3 µm pixels, i.e. f = 0.96 mm / tan(22°) = 2.376 mm, at f/4 (ISETCam's
default f-number; the paper's pinhole has none, the f-number only sets the irradiance).
"""
from __future__ import annotations

import math
from pathlib import PurePosixPath
from typing import Literal

from pydantic import Field, field_validator, model_validator

from workbench.errors import InvalidValueError, ParameterError

from workbench.params import Params

OpticsModelName = Literal["pinhole", "diffraction_limited", "thin_lens", "psf_grid", "raytrace", "auto"]

LENS_MODELS = ("psf_grid", "raytrace")
"""Optics levels that trace a real lens and so need lens_file."""
PAPER_SENSOR_WIDTH_MM = 640 * 3e-3
PAPER_HFOV_DEG = 44.0


def focal_length_for_fov_mm(hfov_deg: float, sensor_width_mm: float) -> float:
    """Focal length (mm) whose horizontal field of view over `sensor_width_mm` is `hfov_deg`."""
    if not 0 < hfov_deg < 180:
        raise InvalidValueError(f"hfov_deg must be in (0, 180) degrees, got {hfov_deg}")
    if not sensor_width_mm > 0:
        raise InvalidValueError(f"sensor_width_mm must be > 0, got {sensor_width_mm}")
    return sensor_width_mm / 2 / math.tan(math.radians(hfov_deg) / 2)


def fov_deg(focal_length_mm: float, sensor_width_mm: float) -> float:
    """Full field of view (degrees) that `sensor_width_mm` spans at focal length `focal_length_mm`."""
    if not focal_length_mm > 0:
        raise InvalidValueError(f"focal_length_mm must be > 0, got {focal_length_mm}")
    if not sensor_width_mm > 0:
        raise InvalidValueError(f"sensor_width_mm must be > 0, got {sensor_width_mm}")
    return math.degrees(2 * math.atan(sensor_width_mm / 2 / focal_length_mm))


class ErrorBudget(Params):
    """What the 'auto' model may lose against the full model (measured on a slanted-edge probe).

    max_rel_rms_error: RMS of (level − reference) over the RMS of the reference, 0–1.
    max_mtf50_error: |MTF50(level) − MTF50(reference)| / MTF50(reference), 0–1.
    max_distortion_shift_samples: largest allowed displacement (samples) of the frame corner
        between a level's geometry and the lens's traced distortion.
    """

    max_rel_rms_error: float = Field(0.02, gt=0, le=1,
                                     description="largest relative RMS error against the full model (0–1); "
                                                 "optics 'auto' selector")
    max_mtf50_error: float = Field(0.05, gt=0, le=1,
                                   description="largest relative MTF50 error against the full model (0–1); "
                                               "optics 'auto' selector")
    max_distortion_shift_samples: float = Field(0.5, gt=0, le=100,
                                                description="largest frame-corner shift against the lens's "
                                                            "traced distortion (samples); optics 'auto' selector")


MAX_DISTORTION_K = 10.0


class OpticsParams(Params):
    """How radiance becomes sensor-plane irradiance.

    model: the level of detail, a name in OPTICS_MODELS ('auto' lets the selector choose).
    focal_length_mm, f_number: first-order optics. With a lens file, the lens's paraxial focal
        length replaces focal_length_mm (unless scale_lens_to_focal_length scales the lens to
        it) and the stop is resized so the lens's paraxial f-number equals f_number; every
        level then uses the same first-order values.
    transmittance: lens transmittance T in the camera equation, 0–1.
    off_axis: 'cos4th' (ISETCam's fall-off) or 'none'.
    lens_file: a lens library name (resources/lenses/, then the user's lens folder
        workbench.optics.lens.io.user_lens_dir()), for psf_grid/raytrace.
    scale_lens_to_focal_length: scale the prescription so its focal length is focal_length_mm.
    focus_distance_m: object distance in focus; None = focused at the scene distance.
    distortion_k: radial distortion r_d = r·(1 + k1 r² + k2 r⁴ + k3 r⁶), r = image height /
        image distance (the tangent of the field angle); empty = none.
    depth_layers: number of defocus layers of the thin-lens model.
    defocus_kernel: thin-lens blur shape, 'pillbox' (geometric) or 'gaussian' (same 2nd moment).
    psf_field_zones: field heights sampled by the PSF grid (centre to corner).
    psf_azimuths: orientations each off-axis PSF is rotated to (interpolated between).
    psf_wavelengths: wavelengths at which the PSF grid traces PSFs (bands between interpolate).
    psf_depth_nodes: object distances at which the PSF grid traces PSFs when the scene's depth
        varies, evenly spaced in 1/distance (depths between interpolate); the focus distance is
        always a node when it lies inside the scene's depth range (then at least 3 nodes).
    rays_per_sample: exit-pupil rays per output sample of the ray-traced model.
    raytrace_diffraction: the ray-traced model also applies the diffraction OTF of its
        working f-number (geometric blur ⊛ Airy); off = geometric optics only, as PBRT.
    budget: error budget used by 'auto'.
    """

    model: OpticsModelName = Field("pinhole", description="optics level of detail (OPTICS_MODELS); 'auto' lets "
                                                          "the selector pick the cheapest within the budget")
    focal_length_mm: float = Field(round(focal_length_for_fov_mm(PAPER_HFOV_DEG, PAPER_SENSOR_WIDTH_MM), 4),
                                   gt=0, le=2000,
                                   description="focal length (mm) of every level when no lens_file is set (with "
                                               "one, the lens's paraxial focal length is used instead); with the "
                                               "sensor width and focus it sets the field of view")
    f_number: float = Field(4.0, ge=0.5, le=256,
                            description="f-number N (camera equation, defocus, diffraction); a lens file's stop "
                                        "is resized to it; every level")
    transmittance: float = Field(1.0, ge=0, le=1, description="lens transmittance T (0–1); every level")
    off_axis: Literal["cos4th", "none"] = Field(
        "cos4th", description="off-axis fall-off of the lens-free levels: ISETCam's cos⁴ or none; pinhole, "
                              "diffraction_limited, thin_lens")
    lens_file: str | None = Field(None, description="lens prescription under resources/lenses/ (relative path); "
                                                    "psf_grid, raytrace, auto; sets the effective focal length")
    scale_lens_to_focal_length: bool = Field(False, description="scale the prescription to focal_length_mm; "
                                                                "psf_grid, raytrace")
    focus_distance_m: float | None = Field(None, gt=0, description="object distance in focus (m); None = the "
                                                                   "scene distance; sets the image distance, "
                                                                   "so the field of view; every level")
    distortion_k: tuple[float, ...] = Field((), max_length=3,
                                            description="radial distortion k1, k2, k3 of r_d = r(1 + k1 r² + k2 r⁴ "
                                                        "+ k3 r⁶), r = tan(field angle) (unitless); lens-free levels")
    depth_layers: int = Field(8, ge=1, le=64, description="defocus layers (count); thin_lens")
    defocus_kernel: Literal["pillbox", "gaussian"] = Field(
        "pillbox", description="defocus blur shape: geometric pillbox or a Gaussian of the same 2nd moment; thin_lens")
    psf_field_zones: int = Field(5, ge=2, le=32, description="field heights with a traced PSF, centre to "
                                                             "corner (count); psf_grid")
    psf_azimuths: int = Field(8, ge=1, le=64, description="orientations each off-axis PSF is turned to "
                                                          "(count); psf_grid")
    psf_wavelengths: int = Field(3, ge=1, le=64, description="wavelengths with traced PSFs (count); psf_grid")
    psf_depth_nodes: int = Field(3, ge=1, le=16, description="object distances with traced PSFs, even in "
                                                             "1/distance (count); psf_grid")
    rays_per_sample: int = Field(64, ge=1, le=4096, description="exit-pupil rays per output sample (count); "
                                                                "raytrace")
    raytrace_diffraction: bool = Field(True, description="add the Airy pattern of the working f-number to the "
                                                         "traced blur; raytrace and the full lens model")
    budget: ErrorBudget = Field(default_factory=ErrorBudget, description="error budget; optics 'auto' selector")

    @field_validator("lens_file")
    @classmethod
    def _relative_lens_path(cls, v: str | None) -> str | None:
        if v is None:
            return v
        p = PurePosixPath(v.replace("\\", "/"))
        if not v or p.is_absolute() or ".." in p.parts:
            raise InvalidValueError(f"lens_file must be a lens library name (resources/lenses/ or the user's "
                             f"lens folder; no '..', not absolute), got {v!r}")
        from workbench.optics.lens.io import check_library_lens
        check_library_lens(str(p))          # a missing or broken lens is refused here, not at the optics stage
        return str(p)

    @field_validator("distortion_k")
    @classmethod
    def _finite_coefficients(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if not all(math.isfinite(k) and abs(k) <= MAX_DISTORTION_K for k in v):
            raise InvalidValueError(f"distortion_k must be finite numbers within ±{MAX_DISTORTION_K:g} (real lenses: "
                                    f"|k| < 1 with r = tan of the field angle), got {v}")
        return v

    @model_validator(mode="after")
    def _lens_for_lens_models(self):
        if self.model in LENS_MODELS and self.lens_file is None:
            raise ParameterError("lens_file", None, f"optics model '{self.model}' needs a lens file (a prescription "
                                                    "under resources/lenses/, e.g. 'dgauss.50mm')")
        return self

    @property
    def focal_length_m(self) -> float:
        return self.focal_length_mm * 1e-3
