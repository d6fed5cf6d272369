"""First-order (paraxial) optics by y–nu ray-transfer matrices, and focusing.

A paraxial ray is (y, nu) with y the height (mm) and nu = n·u the reduced slope. Refraction at a
surface of curvature c from index n to n' is [[1, 0], [−(n'−n)c, 1]]; a gap t in index n is
[[1, t/n], [0, 1]]. Object and image space are air.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.lens.glass import LINE_D_NM
from workbench.optics.lens.model import Lens


def _matrix(lens: Lens, start: int, stop: int, wavelength_nm: float, gap_after_last: bool) -> np.ndarray:
    """Transfer matrix from just before surface `start` to just after surface `stop - 1`
    (plus the gap after it when gap_after_last)."""
    media = lens.media()
    m = np.eye(2)
    for i in range(start, stop):
        s = lens.surfaces[i]
        n0 = float(media[i].index(wavelength_nm))
        n1 = float(media[i + 1].index(wavelength_nm))
        m = np.array([[1.0, 0.0], [-(n1 - n0) * s.curvature_per_mm, 1.0]]) @ m
        if i < stop - 1 or gap_after_last:
            m = np.array([[1.0, s.thickness_mm / n1], [0.0, 1.0]]) @ m
    return m


def system_matrix(lens: Lens, wavelength_nm: float = LINE_D_NM) -> np.ndarray:
    """ABCD matrix from the first vertex (object side) to the last vertex (image side)."""
    return _matrix(lens, 0, len(lens.surfaces), wavelength_nm, gap_after_last=False)


def marginal_ray_heights(lens: Lens, wavelength_nm: float = LINE_D_NM) -> np.ndarray:
    """Heights at every surface of the paraxial ray entering parallel to the axis at height 1."""
    ys = []
    for i in range(len(lens.surfaces)):
        m = _matrix(lens, 0, i, wavelength_nm, gap_after_last=True) if i else np.eye(2)
        ys.append(m[0, 0])
    return np.array(ys)


def with_aperture_stop(lens: Lens, wavelength_nm: float = LINE_D_NM) -> Lens:
    """`lens` with its aperture stop resolved: the one it has (flagged or read), else the surface
    whose semi-aperture limits the axial beam (largest marginal-ray height / semi-aperture)."""
    if lens.stop_index is not None:
        return lens
    y = marginal_ray_heights(lens, wavelength_nm)
    k = int(np.argmax(np.abs(y) / np.array([s.semi_aperture_mm for s in lens.surfaces])))
    return replace(lens, stop_index=k)


@dataclass(frozen=True)
class ParaxialData:
    """First-order properties at one wavelength. Distances in mm; pupil positions are measured
    along +z: the entrance pupil from the first vertex, the exit pupil from the last vertex."""

    wavelength_nm: float
    efl_mm: float
    bfl_mm: float                 # last vertex → rear focal point (infinity focus)
    ffl_mm: float                 # front focal point → first vertex (object distance giving image at ∞)
    epd_mm: float                 # entrance-pupil diameter
    f_number: float               # efl / epd (infinity)
    entrance_pupil_mm: float
    exit_pupil_mm: float
    exit_pupil_diameter_mm: float
    total_track_mm: float
    stop_index: int

    def fov_deg(self, sensor_size_mm: float) -> float:
        """Full paraxial field of view (deg) across a sensor dimension `sensor_size_mm` at infinity focus."""
        return math.degrees(2.0 * math.atan(0.5 * sensor_size_mm / self.efl_mm))

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def paraxial(lens: Lens, wavelength_nm: float = LINE_D_NM) -> ParaxialData:
    """EFL, BFL, pupils and f-number of `lens` at `wavelength_nm`."""
    (A, _), (C, D) = system_matrix(lens, wavelength_nm).tolist()
    if abs(C) < 1e-15:
        raise InvalidValueError(f"lens {lens.name!r} is afocal (zero power): no focal length")
    efl = -1.0 / C
    k = with_aperture_stop(lens).stop_index
    stop = lens.surfaces[k]
    # Entrance pupil: image of the stop through the surfaces in front of it.
    (a, b), _ = (_matrix(lens, 0, k, wavelength_nm, gap_after_last=True) if k else np.eye(2)).tolist()
    ep_z = b / a
    epd = 2.0 * stop.semi_aperture_mm / abs(a)
    # Exit pupil: image of the stop through the surfaces behind it (stop plane itself included).
    (a2, b2), (c2, d2) = _matrix(lens, k, len(lens.surfaces), wavelength_nm, gap_after_last=False).tolist()
    if abs(d2) < 1e-15:
        xp_z, xpd = math.inf, math.inf
    else:
        xp_z = -b2 / d2
        xpd = 2.0 * stop.semi_aperture_mm * abs(a2 + xp_z * c2)
    return ParaxialData(wavelength_nm=float(wavelength_nm), efl_mm=efl, bfl_mm=-A / C, ffl_mm=-D / C,
                        epd_mm=epd, f_number=efl / epd, entrance_pupil_mm=ep_z, exit_pupil_mm=xp_z,
                        exit_pupil_diameter_mm=xpd, total_track_mm=lens.total_track_mm, stop_index=k)


MAX_FOCAL_LENGTH_MM = 1e5      # 100 m: a "lens" of less power is a window (a flat plate), not a lens


def imaging_problem(lens: Lens) -> str | None:
    """Why `lens` cannot form a real image of a distant object behind its last vertex (None when it
    can): no power, negative power (a diverging lens), or a rear focal point inside the lens."""
    try:
        p = paraxial(lens)
    except InvalidValueError as exc:
        return str(exc)
    if p.efl_mm <= 0:
        return (f"its focal length is negative (EFL={p.efl_mm:.4g} mm): a diverging lens forms no real image; "
                "check the signs of the radii (positive: centre of curvature behind the surface)")
    if p.efl_mm > MAX_FOCAL_LENGTH_MM:
        return (f"it has almost no power (EFL={p.efl_mm:.4g} mm, more than {MAX_FOCAL_LENGTH_MM:g} mm): "
                "a window or flat plate, not a lens")
    if p.bfl_mm <= 0:
        return (f"its rear focal point lies inside the lens (BFL={p.bfl_mm:.4g} mm from the last vertex): "
                "there is no room for a sensor")
    return None


def image_distance_mm(lens: Lens, object_distance_m: float, wavelength_nm: float = LINE_D_NM) -> float:
    """Paraxial distance (mm) from the last vertex to the image of an axial object
    `object_distance_m` in front of the first vertex (inf = infinity)."""
    (A, B), (C, D) = system_matrix(lens, wavelength_nm).tolist()
    if math.isinf(object_distance_m):
        return -A / C
    s = object_distance_m * 1e3
    den = C * s + D
    s_img = -(A * s + B) / den if den != 0 else math.inf
    if not math.isfinite(s_img) or s_img <= 0:
        ffl = -D / C
        raise InvalidValueError(f"lens {lens.name!r} cannot focus at object_distance_m={object_distance_m:g}: "
                         f"the image would be virtual or at infinity; objects must be farther than "
                         f"{max(ffl, 0) * 1e-3:.6g} m from the first vertex (front focal distance), "
                         "with the image behind the last vertex")
    return s_img


def lateral_magnification(lens: Lens, object_distance_m: float, wavelength_nm: float = LINE_D_NM) -> float:
    """Paraxial lateral magnification (image height / object height, negative for an inverted
    image) of an object `object_distance_m` in front of the first vertex onto its image (0 at
    infinity)."""
    if math.isinf(object_distance_m):
        return 0.0
    (A, _), (C, _) = system_matrix(lens, wavelength_nm).tolist()
    return A + image_distance_mm(lens, object_distance_m, wavelength_nm) * C


def focus(lens: Lens, object_distance_m: float, wavelength_nm: float = LINE_D_NM) -> Lens:
    """The lens with its sensor moved (paraxially) to focus an object `object_distance_m` in front of
    the first vertex; inf focuses at infinity. ValueError when it cannot focus that close."""
    if not (object_distance_m > 0):
        raise InvalidValueError(f"object_distance_m={object_distance_m}: must be > 0 (or inf)")
    d = image_distance_mm(lens, object_distance_m, wavelength_nm)
    return lens.with_image_distance(d)


def sensor_distance_mm(lens: Lens) -> float:
    """Last vertex → sensor: the lens's image distance, or the d-line BFL when unset (infinity focus)."""
    if lens.image_distance_mm is not None:
        return lens.image_distance_mm
    bfl = paraxial(lens).bfl_mm
    if bfl <= 0:
        raise InvalidValueError(f"lens {lens.name!r}: {imaging_problem(lens)}")
    return bfl


def sensor_z_mm(lens: Lens) -> float:
    """z of the sensor plane (first vertex at 0)."""
    return lens.total_track_mm + sensor_distance_mm(lens)
