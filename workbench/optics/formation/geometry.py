"""First-order image geometry and radiometry shared by every level of detail.

The camera geometry (CameraGeometry: effective focal length, focus → image distance → field of
view and sample spacing), thin-lens conjugates, ISETCam's camera equation, the off-axis
fall-off and radial distortion. Lengths in metres unless a name says otherwise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.params import OpticsParams, fov_deg as _fov_deg
from workbench.scene.types import Scene


def image_distance_m(focal_length_m: float, object_distance_m: float) -> float:
    """Thin-lens image distance 1/(1/f − 1/s) for an object at s (inf → f)."""
    if not focal_length_m > 0:
        raise InvalidValueError(f"focal_length_m must be > 0, got {focal_length_m}")
    if math.isinf(object_distance_m):
        return focal_length_m
    if not object_distance_m > focal_length_m:
        raise InvalidValueError(f"object distance {object_distance_m} m must exceed the focal length "
                         f"{focal_length_m} m for a real image")
    return 1.0 / (1.0 / focal_length_m - 1.0 / object_distance_m)


@dataclass(frozen=True)
class CameraGeometry:
    """The camera's first-order geometry: the one source every optics level, scene stage, the
    full-lens render and the pipeline's cache keys read (DESIGN.md §3).

    focal_length_m: effective focal length: the lens file's paraxial EFL when optics.lens_file
        is set, else optics.focal_length_mm. focus_distance_m: object distance in focus (m).
    image_distance_m: the distance (m) at which a pinhole at the entrance pupil images the focus
        plane as the optics do: its thin-lens conjugate, or |m|·s with a lens file's paraxial
        magnification m (lens_setup.pinhole_image_distance_m).
    sensor_width_m: width the `shape` = (rows, cols) optical-image samples span on the sensor.
    """

    focal_length_m: float
    focus_distance_m: float
    image_distance_m: float
    sensor_width_m: float
    shape: tuple[int, int]

    @property
    def sample_spacing_m(self) -> float:
        """Optical-image sample spacing on the sensor (m): pixel pitch / oversample for a project."""
        return self.sensor_width_m / self.shape[1]

    @property
    def sensor_height_m(self) -> float:
        return self.sample_spacing_m * self.shape[0]

    @property
    def hfov_deg(self) -> float:
        """Horizontal field of view (deg) of the sensor width at the image distance."""
        return _fov_deg(self.image_distance_m * 1e3, self.sensor_width_m * 1e3)

    @property
    def magnification(self) -> float:
        """Lateral magnification of the focus plane, −image_distance_m / focus_distance_m (0 at infinity)."""
        return 0.0 if math.isinf(self.focus_distance_m) else -self.image_distance_m / self.focus_distance_m


def camera_geometry(params: OpticsParams, default_focus_m: float, shape: tuple[int, int], *,
                    sensor_width_m: float | None = None, fov_deg: float | None = None) -> CameraGeometry:
    """The geometry of `params` on `shape` = (rows, cols) samples: focused on
    params.focus_distance_m, else `default_focus_m` (the scene distance); the samples span
    `sensor_width_m`, or the horizontal `fov_deg` at the image distance (give exactly one)."""
    from workbench.optics.formation.lens_setup import effective_focal_length_m, pinhole_image_distance_m
    if (sensor_width_m is None) == (fov_deg is None):
        raise InvalidValueError("camera_geometry: give exactly one of sensor_width_m or fov_deg")
    rows, cols = (int(shape[0]), int(shape[1]))
    if rows < 1 or cols < 1:
        raise InvalidValueError(f"camera_geometry: shape must be at least 1×1 samples, got {shape}")
    focus_m = params.focus_distance_m if params.focus_distance_m is not None else float(default_focus_m)
    f_m = effective_focal_length_m(params)
    d_m = image_distance_m(f_m, focus_m) if params.lens_file is None else pinhole_image_distance_m(params, focus_m)
    if fov_deg is not None:
        if not 0 < fov_deg < 180:
            raise InvalidValueError(f"fov_deg={fov_deg}: must be in (0, 180) degrees")
        sensor_width_m = 2.0 * d_m * math.tan(math.radians(fov_deg) / 2.0)
    if not (math.isfinite(sensor_width_m) and sensor_width_m > 0):
        raise InvalidValueError(f"sensor_width_m={sensor_width_m}: must be a finite number > 0")
    return CameraGeometry(float(f_m), float(focus_m), float(d_m),
                          float(sensor_width_m), (rows, cols))


def scene_geometry(scene: Scene, params: OpticsParams, camera: CameraGeometry | None = None) -> CameraGeometry:
    """`camera` (the geometry the scene was sampled for) after checking that it fits the scene,
    else the geometry of a scene sampled over scene.fov_deg, focused at the scene distance
    unless params.focus_distance_m says otherwise."""
    if camera is None:
        return camera_geometry(params, scene.distance_m, scene.shape, fov_deg=scene.fov_deg)
    if tuple(camera.shape) != tuple(scene.shape):
        raise InvalidValueError(f"camera geometry of {camera.shape[0]}×{camera.shape[1]} samples does not fit "
                         f"the scene of {scene.shape[0]}×{scene.shape[1]}")
    return camera


def sample_positions_m(shape: tuple[int, int], spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) image-plane coordinates of sample centres, origin on the optical axis, y up."""
    rows, cols = shape
    x = (np.arange(cols) + 0.5 - cols / 2.0) * spacing_m
    y = (rows / 2.0 - np.arange(rows) - 0.5) * spacing_m
    return np.meshgrid(x, y)


def camera_equation_factor(f_number: float, magnification_: float, transmittance: float = 1.0) -> float:
    """On-axis E/L (sr): π T / (1 + 4 N² (1 + |m|)²), ISETCam's camera equation.

    Equal to π T sin²θ with tan θ = 1/(2 N (1 + |m|)), the exact irradiance under a uniform
    Lambertian disk (the paraxial form is π T / (4 N² (1 + |m|)²))."""
    return math.pi * transmittance / (1.0 + 4.0 * f_number ** 2 * (1.0 + abs(magnification_)) ** 2)


def cos4th_falloff(radius_m: np.ndarray, image_distance: float, f_number: float,
                   magnification_: float, image_diagonal_m: float) -> np.ndarray:
    """ISETCam's off-axis fall-off relative to the axis.

    For an image plane more than 10 diagonals away: (d/√(d²+r²))⁴. Otherwise the exact
    irradiance of a uniform circular exit pupil (half-angle θa, tan θa = 1/(2N(1+|m|))) at
    field angle φ (tan φ = r/d), divided by its on-axis value π sin²θa:
    (π/2)[1 − (1 − tan²θa + tan²φ)/√(tan⁴φ + 2 tan²φ (1 − tan²θa) + 1/cos⁴θa)] / (π sin²θa).
    """
    r = np.asarray(radius_m, dtype=np.float64)
    t2 = (r / image_distance) ** 2
    if image_distance > 10.0 * image_diagonal_m:
        return 1.0 / (1.0 + t2) ** 2
    ta2 = 1.0 / (2.0 * f_number * (1.0 + abs(magnification_))) ** 2
    sin2a = ta2 / (1.0 + ta2)
    a = 1.0 - ta2 + t2
    root = np.sqrt(a * a + 4.0 * ta2)                 # = the root above: its radicand is a² + 4 tan²θa
    # 1 − a/root without cancellation (it went negative far off axis): (root − a)/root = 4 tan²θa/(root (root + a))
    rest = np.where(a > 0, 4.0 * ta2 / (root * (root + np.abs(a))), 1.0 - a / root)
    return 0.5 * rest / sin2a


def undistort_radius(r_distorted: np.ndarray, k: tuple[float, ...]) -> np.ndarray:
    """Invert r_d = r (1 + k1 r² + k2 r⁴ + k3 r⁶) by Newton's method (r = tan of field angle)."""
    rd = np.asarray(r_distorted, dtype=np.float64)
    coeffs = tuple(k) + (0.0,) * (3 - len(k))
    r = rd.copy()
    for _ in range(30):
        r2 = r * r
        f = r * (1 + coeffs[0] * r2 + coeffs[1] * r2 ** 2 + coeffs[2] * r2 ** 3) - rd
        df = 1 + 3 * coeffs[0] * r2 + 5 * coeffs[1] * r2 ** 2 + 7 * coeffs[2] * r2 ** 3
        if np.any(df <= 0):
            raise InvalidValueError(f"distortion_k {k} is not monotonic over the field (the mapping "
                             "folds over); use smaller coefficients")
        step = f / df
        r = r - step
        if np.max(np.abs(step)) < 1e-12:
            break
    return r


def radial_resample(plane: np.ndarray, spacing_m: float, scale: np.ndarray) -> np.ndarray:
    """Resample an H×W plane: output at (x, y) = input at (x·scale, y·scale), coordinates from
    the optical axis. Convention shared by every level: a scene sample is a uniform patch (its
    value is the patch mean) and an output sample is the irradiance at its centre, so this is
    nearest-sample lookup (no smoothing; a patch smaller than the local sample spacing can fall
    between samples, as it would for any point sampling). Up to one patch beyond the border
    the edge patch continues; farther out 0."""
    rows, cols = plane.shape
    x, y = sample_positions_m((rows, cols), spacing_m)
    col = np.floor(x * scale / spacing_m + cols / 2.0).astype(np.int64)
    row = np.floor(rows / 2.0 - y * scale / spacing_m).astype(np.int64)
    inside = (col >= -1) & (col <= cols) & (row >= -1) & (row <= rows)
    return np.where(inside, plane[np.clip(row, 0, rows - 1), np.clip(col, 0, cols - 1)], 0.0)


def distort_image(image: np.ndarray, spacing_m: float, image_distance: float,
                  k: tuple[float, ...]) -> np.ndarray:
    """Irradiance of an undistorted H×W×C image on the distorted sensor grid.

    The output sample at distorted height r_d takes the input at r_u (radial_resample) times the
    area Jacobian dA_u/dA_d = (r_u/r_d)·(dr_u/dr_d): distortion moves the light a scene patch sends
    through the pupil, it neither creates nor removes it, so total flux is kept (barrel
    distortion brightens the corners it compresses). Field outside the input is 0."""
    if not k or not any(k):
        return image
    x, y = sample_positions_m(image.shape[:2], spacing_m)
    rd = np.hypot(x, y) / image_distance
    ru = undistort_radius(rd, k)
    scale = np.divide(ru, rd, out=np.ones_like(rd), where=rd > 0)
    k1, k2, k3 = tuple(k) + (0.0,) * (3 - len(k))
    r2 = ru * ru
    jacobian = scale / (1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 ** 2 + 7.0 * k3 * r2 ** 3)   # dr_d/dr_u > 0
    out = np.empty_like(image)
    for c in range(image.shape[2]):
        out[..., c] = radial_resample(image[..., c], spacing_m, scale) * jacobian
    return out
