"""Optical media: the glass catalogue (Sellmeier), (n_d, V_d) fallback, constant and tabulated indices.

A `Material` is written in lens files by its `spec`:
  "air"                    n = 1
  "N-BK7"                  a catalogue glass (resources/glass/*.json, Schott Sellmeier, λ in µm)
  "1.67"                   a constant index (PBRT .dat files carry only n_d)
  "1.67/47.1"              n_d / V_d: Cauchy A + B/λ² through the d line with the given Abbe number
  {"wavelength_nm": [...], "n": [...]}   a table, linearly interpolated (ISETCam/iset3d `ior` tables)
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.resource_dir import RESOURCES

LINE_D_NM = 587.5618
LINE_F_NM = 486.1327
LINE_C_NM = 656.2725

GLASS_DIR = RESOURCES / "glass"


@lru_cache(maxsize=1)
def glass_catalogue() -> dict[str, dict]:
    """All catalogue glasses by upper-case name: {'K': [..3], 'L': [..3], 'nd', 'vd', 'catalogue'}."""
    out: dict[str, dict] = {}
    for path in sorted(GLASS_DIR.glob("*.json")):
        data = json.loads(path.read_text())
        for name, entry in data["glasses"].items():
            out[name.upper()] = {**entry, "name": name, "catalogue": path.stem}
    return out


def sellmeier_index(K, L, wavelength_nm) -> np.ndarray:
    """Refractive index n(λ) from Sellmeier coefficients: n² − 1 = Σ Kᵢλ²/(λ² − Lᵢ), λ in µm."""
    lam2 = (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3) ** 2
    n2 = 1.0 + sum(k * lam2 / (lam2 - l) for k, l in zip(K, L))
    return np.sqrt(n2)


@dataclass(frozen=True)
class Material:
    """A medium with a wavelength-dependent index. Build it with `material(spec)`."""

    spec: str | tuple
    kind: str                      # 'constant' | 'abbe' | 'sellmeier' | 'table'
    nd: float
    vd: float = float("inf")
    K: tuple = ()
    L: tuple = ()
    table_nm: tuple = ()
    table_n: tuple = ()

    def index(self, wavelength_nm) -> np.ndarray | float:
        """Refractive index at wavelength(s) in nm (float64; a scalar in gives a float out)."""
        wl = np.asarray(wavelength_nm, dtype=np.float64)
        if self.kind == "constant":
            n = np.full(wl.shape, self.nd)
        elif self.kind == "sellmeier":
            n = sellmeier_index(self.K, self.L, wl)
        elif self.kind == "abbe":
            A, B = self.cauchy_coefficients()
            n = A + B / (wl * 1e-3) ** 2
        else:
            n = np.interp(wl, np.asarray(self.table_nm), np.asarray(self.table_n))
        return float(n) if n.ndim == 0 else n

    def cauchy_coefficients(self) -> tuple[float, float]:
        """(A, B) of n = A + B/λ² (λ in µm) through n_d with Abbe number V_d (the 'n/V' fallback):
        B = (n_d − 1)/(V_d (λF⁻² − λC⁻²)), A = n_d − B/λd²."""
        inv2 = lambda w: (w * 1e-3) ** -2  # noqa: E731  (1/λ², λ in µm)
        B = (self.nd - 1.0) / (self.vd * (inv2(LINE_F_NM) - inv2(LINE_C_NM)))
        return self.nd - B * inv2(LINE_D_NM), B

    @property
    def is_air(self) -> bool:
        return self.kind == "constant" and self.nd == 1.0

    def to_json(self):
        """The spec as written in lens JSON files."""
        if self.kind == "table":
            return {"wavelength_nm": list(self.table_nm), "n": list(self.table_n)}
        return self.spec


def material(spec) -> Material:
    """Parse a medium spec (see module docstring). Raises ValueError naming the spec on bad input."""
    if isinstance(spec, Material):
        return spec
    if isinstance(spec, dict):
        try:
            wl = tuple(float(v) for v in spec["wavelength_nm"])
            n = tuple(float(v) for v in spec["n"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidValueError(f"material table {spec!r}: needs numeric lists 'wavelength_nm' and 'n'") from exc
        if len(wl) != len(n) or len(wl) < 1 or any(np.diff(wl) <= 0) or min(n) < 1.0:
            raise InvalidValueError(f"material table {spec!r}: needs equal-length lists, wavelengths "
                             "increasing, indices >= 1")
        nd = float(np.interp(LINE_D_NM, wl, n))
        return Material(spec=("table",), kind="table", nd=nd, table_nm=wl, table_n=n)
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        spec = repr(float(spec))
    if not isinstance(spec, str) or not spec.strip():
        raise InvalidValueError(f"material {spec!r}: expected 'air', a glass name, 'n', 'n/V' or an index table")
    s = spec.strip()
    if s.lower() == "air":
        return Material(spec="air", kind="constant", nd=1.0)
    cat = glass_catalogue()
    if s.upper() in cat:
        g = cat[s.upper()]
        return Material(spec=g["name"], kind="sellmeier", nd=float(g["nd"]), vd=float(g["vd"]),
                        K=tuple(g["K"]), L=tuple(g["L"]))
    try:
        parts = [float(p) for p in s.split("/")]
    except ValueError:
        raise InvalidValueError(f"material {spec!r}: not a catalogue glass ({', '.join(sorted(cat))}) "
                         "nor a number 'n' or 'n/V'") from None
    if len(parts) not in (1, 2) or not all(np.isfinite(parts)) or parts[0] < 1.0:
        raise InvalidValueError(f"material {spec!r}: index must be a finite number >= 1, optionally '/V' (Abbe)")
    if len(parts) == 1:
        if parts[0] == 1.0:
            return Material(spec="air", kind="constant", nd=1.0)
        return Material(spec=s, kind="constant", nd=parts[0])
    if parts[1] <= 0:
        raise InvalidValueError(f"material {spec!r}: Abbe number must be > 0")
    return Material(spec=s, kind="abbe", nd=parts[0], vd=parts[1])


AIR = material("air")
