"""The lens prescription: surfaces in order from object to image, lengths in mm.

Coordinates: z along the optical axis, the first vertex at z = 0, light travelling +z from the
object to the image. Each surface's `thickness_mm` is the axial gap to the next vertex and its
`material` is the medium *after* it (the PBRT/ISETCam convention); the gap after the last surface
is the lens's `image_distance_mm` (last vertex → sensor), set by focusing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.lens.glass import AIR, Material, material

MAX_SEMI_APERTURE_MM = 1e5      # 100 m: larger than any lens; 1e308 overflowed the ray tracer


@dataclass(frozen=True)
class Surface:
    """One refracting surface (or the aperture stop).

    curvature_per_mm: 1/R (0 for a flat surface or the stop); sag
        z = c r²/(1 + √(1 − (1+conic) c² r²)) + Σᵢ asphere_coeffs[i] · r^(2i+2)
        (even asphere; coefficients of r², r⁴, r⁶ … as Zemax's EVENASPH PARM 1, 2, 3 …).
    thickness_mm: axial distance to the next vertex (ignored for the last surface).
    material: medium after the surface.
    semi_aperture_mm: clear radius; rays beyond it are blocked.
    """

    curvature_per_mm: float
    thickness_mm: float
    material: Material
    semi_aperture_mm: float
    is_stop: bool = False
    conic: float = 0.0
    asphere_coeffs: tuple[float, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "material", material(self.material))
        object.__setattr__(self, "asphere_coeffs", tuple(float(a) for a in self.asphere_coeffs))
        for name in ("curvature_per_mm", "thickness_mm", "semi_aperture_mm", "conic"):
            v = getattr(self, name)
            try:
                fv = float(v)
            except (TypeError, ValueError):
                fv = math.nan
            if isinstance(v, bool) or not math.isfinite(fv):
                raise InvalidValueError(f"Surface.{name}={v!r}: must be a finite number")
            object.__setattr__(self, name, fv)
        if not 0 < self.semi_aperture_mm <= MAX_SEMI_APERTURE_MM:       # its square must not overflow the tracer
            raise InvalidValueError(f"Surface.semi_aperture_mm={self.semi_aperture_mm}: must be > 0 and at most "
                                    f"{MAX_SEMI_APERTURE_MM:g} mm")
        if self.thickness_mm < 0:
            raise InvalidValueError(f"Surface.thickness_mm={self.thickness_mm}: must be >= 0")
        if not all(math.isfinite(a) for a in self.asphere_coeffs):
            raise InvalidValueError(f"Surface.asphere_coeffs={self.asphere_coeffs}: must be finite")
        if self.is_stop and (self.curvature_per_mm != 0 or self.asphere_coeffs):
            raise InvalidValueError("Surface.is_stop: the aperture stop must be flat (curvature 0, no asphere)")

    @classmethod
    def from_radius(cls, radius_mm: float, thickness_mm: float, material_spec, semi_aperture_mm: float,
                    **kw) -> "Surface":
        """Build from a radius in mm (0 or ±inf = flat)."""
        c = 0.0 if radius_mm == 0 or math.isinf(radius_mm) else 1.0 / radius_mm
        return cls(c, thickness_mm, material(material_spec), semi_aperture_mm, **kw)

    @property
    def radius_mm(self) -> float:
        """Radius of curvature in mm (inf for a flat surface)."""
        return math.inf if self.curvature_per_mm == 0 else 1.0 / self.curvature_per_mm

    @property
    def reaches_its_aperture(self) -> bool:
        """Whether the conic is defined out to the clear radius ((1+k) c² r² ≤ 1: a sphere's clear
        radius is at most |R|). The tracer copes either way (rays beyond miss); a lens file may not."""
        return (1.0 + self.conic) * (self.curvature_per_mm * self.semi_aperture_mm) ** 2 <= 1.0 + 1e-9

    @property
    def is_aspheric(self) -> bool:
        return any(a != 0 for a in self.asphere_coeffs)

    def sag_mm(self, r_mm) -> np.ndarray:
        """Surface z (mm, relative to its vertex) at radial distance r (mm); NaN-free inside its domain."""
        rho = np.asarray(r_mm, dtype=np.float64) ** 2
        c, k = self.curvature_per_mm, self.conic
        root = np.sqrt(np.maximum(1.0 - (1.0 + k) * c * c * rho, 0.0))
        z = c * rho / (1.0 + root)
        for i, a in enumerate(self.asphere_coeffs):
            z = z + a * rho ** (i + 1)
        return z


@dataclass(frozen=True)
class Lens:
    """A sequential lens. `image_distance_mm` (last vertex → sensor) None means focused at infinity.

    stop_index: index of the aperture stop: the surface flagged is_stop, else resolved when the lens
        is read (load_lens: the surface limiting the axial beam, paraxial.with_aperture_stop);
        None only for a lens built without one, which paraxial.with_aperture_stop resolves.
    """

    surfaces: tuple[Surface, ...]
    name: str = ""
    image_distance_mm: float | None = None
    description: str = ""
    meta: dict = field(default_factory=dict, compare=False)
    stop_index: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "surfaces", tuple(self.surfaces))
        if not self.surfaces:
            raise InvalidValueError(f"Lens {self.name!r}: needs at least one surface")
        flagged = [i for i, s in enumerate(self.surfaces) if s.is_stop]
        if len(flagged) > 1:
            raise InvalidValueError(f"Lens {self.name!r}: more than one surface is marked as the stop")
        if flagged and self.stop_index not in (None, flagged[0]):
            raise InvalidValueError(f"Lens.stop_index={self.stop_index}: surface {flagged[0]} is marked as the stop")
        if flagged:
            object.__setattr__(self, "stop_index", flagged[0])
        elif self.stop_index is not None and not (isinstance(self.stop_index, int)
                                                  and 0 <= self.stop_index < len(self.surfaces)):
            raise InvalidValueError(f"Lens.stop_index={self.stop_index!r}: must be a surface index "
                             f"0 … {len(self.surfaces) - 1}")
        if not self.surfaces[-1].material.is_air:
            raise InvalidValueError(f"Lens {self.name!r}: the last surface must be followed by air, "
                             f"got {self.surfaces[-1].material.spec!r}")
        if self.image_distance_mm is not None and not (math.isfinite(self.image_distance_mm)
                                                       and self.image_distance_mm > 0):
            raise InvalidValueError(f"Lens.image_distance_mm={self.image_distance_mm}: must be a finite "
                             "number > 0 (or None for infinity focus)")

    @property
    def vertex_z_mm(self) -> np.ndarray:
        """z of every vertex (first at 0)."""
        t = np.array([s.thickness_mm for s in self.surfaces[:-1]], dtype=np.float64)
        return np.concatenate(([0.0], np.cumsum(t)))

    @property
    def total_track_mm(self) -> float:
        """First vertex → last vertex."""
        return float(self.vertex_z_mm[-1])

    def media(self) -> list[Material]:
        """Medium before each surface, plus the image medium: len = n_surfaces + 1."""
        return [AIR] + [s.material for s in self.surfaces]

    def with_image_distance(self, image_distance_mm: float | None) -> "Lens":
        return replace(self, image_distance_mm=image_distance_mm)

    def with_stop_semi_aperture(self, semi_aperture_mm: float) -> "Lens":
        """The same lens with the stop opened or closed to `semi_aperture_mm`."""
        i = self.stop_index
        if i is None:
            raise InvalidValueError(f"lens {self.name!r} has no resolved aperture stop; read it with load_lens "
                             "or pass it through paraxial.with_aperture_stop")
        surfs = list(self.surfaces)
        surfs[i] = replace(surfs[i], semi_aperture_mm=semi_aperture_mm)
        return replace(self, surfaces=tuple(surfs))

    def scaled(self, factor: float, name: str | None = None) -> "Lens":
        """All lengths multiplied by `factor` (focal length scales, f-number and field do not)."""
        if not (math.isfinite(factor) and factor > 0):
            raise InvalidValueError(f"scale factor={factor}: must be a finite number > 0")
        surfs = tuple(replace(s, curvature_per_mm=s.curvature_per_mm / factor,
                              thickness_mm=s.thickness_mm * factor,
                              semi_aperture_mm=s.semi_aperture_mm * factor,
                              asphere_coeffs=tuple(a * factor ** (1 - 2 * (i + 1))
                                                   for i, a in enumerate(s.asphere_coeffs)))
                      for s in self.surfaces)
        d = None if self.image_distance_mm is None else self.image_distance_mm * factor
        return replace(self, surfaces=surfs, image_distance_mm=d,
                       name=self.name if name is None else name)
