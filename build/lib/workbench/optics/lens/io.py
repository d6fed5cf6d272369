"""Lens files: ISETCam JSON (read/write), PBRT .dat (read/write), Zemax .zmx subset (read).

`load_lens(path)` also accepts a bare name of a file in resources/lenses/ ("dgauss.50mm").
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

from workbench.optics.lens.glass import AIR, material
from workbench.optics.lens.model import Lens, Surface
from workbench.spectra import RESOURCES

LENS_DIR = RESOURCES / "lenses"
_FORMATS = (".json", ".dat", ".zmx")


def available_lenses() -> list[str]:
    """Names of the lenses shipped in resources/lenses/."""
    return sorted(p.name[: -len(p.suffix)] for p in LENS_DIR.iterdir() if p.suffix in _FORMATS)


def resolve_lens_path(path_or_name) -> Path:
    """A path to an existing lens file, or the shipped file with that name."""
    p = Path(path_or_name)
    if p.is_file():
        return p
    for ext in ("",) + _FORMATS:
        q = LENS_DIR / f"{path_or_name}{ext}"
        if q.is_file():
            return q
    raise FileNotFoundError(f"lens {str(path_or_name)!r}: no such file, and not a shipped lens "
                            f"(available: {', '.join(available_lenses())})")


def load_lens(path) -> Lens:
    """Read a lens by file extension: .json (ISETCam), .dat (PBRT), .zmx (Zemax subset)."""
    p = resolve_lens_path(path)
    ext = p.suffix.lower()
    raw = p.read_bytes()
    # Zemax often writes UTF-16 with a byte-order mark.
    encoding = "utf-16" if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8-sig"
    text = raw.decode(encoding, errors="replace")
    name = p.name[: -len(p.suffix)]
    if ext == ".json":
        return lens_from_json(json.loads(text), default_name=name)
    if ext == ".dat":
        return lens_from_dat(text, name=name)
    if ext == ".zmx":
        return lens_from_zmx(text, name=name)
    raise ValueError(f"lens file {str(p)!r}: unknown extension {ext!r}; allowed: {', '.join(_FORMATS)}")


def save_lens(lens: Lens, path) -> Path:
    """Write `lens` by extension (.json or .dat), atomically."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".json":
        text = json.dumps(lens_to_json(lens), indent=1)
    elif ext == ".dat":
        text = lens_to_dat(lens)
    else:
        raise ValueError(f"save_lens: extension {ext!r} of {str(p)!r} not writable; allowed: .json, .dat")
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=p.name, suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, p)
    return p


# ---------------------------------------------------------------- ISETCam JSON
def lens_from_json(data: dict, default_name: str = "") -> Lens:
    """ISETCam/iset3d lens JSON: surfaces of radius, thickness, ior (number or [[λ],[n]]),
    semi_aperture (mm); the stop has radius 0 and ior 0. Our extensions: 'glass' (a material spec),
    'is_stop', 'conic_constant', 'aspheric_coefficients' (r², r⁴ …), top-level 'image_distance_mm'."""
    if not isinstance(data, dict) or not isinstance(data.get("surfaces"), list):
        raise ValueError("lens JSON: expected an object with a 'surfaces' list")
    surfaces = []
    prev = AIR
    for i, s in enumerate(data["surfaces"]):
        try:
            radius = float(s["radius"])
            thickness = float(s["thickness"])
            sa = s["semi_aperture"]
            sa = float(max(sa) if isinstance(sa, list) else sa)   # [x, y] semi-axes: circle of the larger
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"lens JSON surface {i}: needs numeric 'radius', 'thickness', "
                             f"'semi_aperture' ({exc})") from None
        ior = s.get("ior", 1.0)
        is_stop = bool(s.get("is_stop", radius == 0 and ior == 0 and "glass" not in s))
        if "glass" in s:
            med = material(s["glass"])
        elif is_stop or ior == 0:
            med = prev
        elif isinstance(ior, list):
            if len(ior) != 2:
                raise ValueError(f"lens JSON surface {i}: 'ior' table must be [[wavelengths nm], [n]]")
            med = material({"wavelength_nm": ior[0], "n": ior[1]})
        else:
            med = material(ior)
        try:
            surf = Surface.from_radius(radius, thickness, med, sa, is_stop=is_stop,
                                       conic=float(s.get("conic_constant", 0.0)),
                                       asphere_coeffs=tuple(s.get("aspheric_coefficients", ()) or ()))
        except ValueError as exc:
            raise ValueError(f"lens JSON surface {i}: {exc}") from None
        surfaces.append(surf)
        prev = med
    d = data.get("image_distance_mm")
    return Lens(tuple(surfaces), name=str(data.get("name", default_name)),
                image_distance_mm=None if d is None else float(d),
                description=str(data.get("description", "")), meta=dict(data.get("metadata", {})))


def lens_to_json(lens: Lens) -> dict:
    """ISETCam-compatible JSON (ior = n_d, stop radius 0 / ior 0) with our exact-material extensions."""
    from workbench.optics.lens.paraxial import paraxial
    surfs = []
    for s in lens.surfaces:
        e = {"radius": 0.0 if s.curvature_per_mm == 0 else s.radius_mm, "thickness": s.thickness_mm,
             "ior": 0.0 if s.is_stop else s.material.nd, "semi_aperture": s.semi_aperture_mm}
        if s.is_stop:
            e["is_stop"] = True
        else:
            e["glass"] = s.material.to_json()
            if s.curvature_per_mm == 0:
                e["is_stop"] = False
        if s.conic:
            e["conic_constant"] = s.conic
        if s.asphere_coeffs:
            e["aspheric_coefficients"] = list(s.asphere_coeffs)
        surfs.append(e)
    p = paraxial(lens)
    out = {"name": lens.name, "description": lens.description, "surfaces": surfs,
           "metadata": {**lens.meta, "focalLength": p.efl_mm * 1e-3, "fNumber": p.f_number}}
    if lens.image_distance_mm is not None:
        out["image_distance_mm"] = lens.image_distance_mm
    return out


# ---------------------------------------------------------------- PBRT .dat
def lens_from_dat(text: str, name: str = "") -> Lens:
    """PBRT realistic-camera lens: rows 'radius thickness n aperture_diameter' (mm, object → image);
    radius 0 is the stop; n is the index after the surface (0 at the stop); '#' starts a comment.
    Indices are constant (the format has no dispersion)."""
    surfaces = []
    prev = AIR
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        try:
            r, t, n, diam = (float(v) for v in line.split())
        except ValueError:
            raise ValueError(f"PBRT lens line {lineno}: expected 4 numbers 'radius thickness n diameter', "
                             f"got {line!r}") from None
        stop = r == 0
        med = prev if stop or n == 0 else material(n)
        try:
            surfaces.append(Surface.from_radius(r, t, med, diam / 2.0, is_stop=stop))
        except ValueError as exc:
            raise ValueError(f"PBRT lens line {lineno}: {exc}") from None
        prev = med
    if not surfaces:
        raise ValueError("PBRT lens file has no surfaces")
    last_t = surfaces[-1].thickness_mm
    return Lens(tuple(surfaces), name=name, image_distance_mm=last_t if last_t > 0 else None)


_DAT_FLAT_RADIUS_MM = 1e6


def lens_to_dat(lens: Lens) -> str:
    """PBRT .dat text. Only n_d is written (dispersion is lost); flat glass faces are written as
    radius 1e6 mm because PBRT reads radius 0 as the stop."""
    lines = [f"# {lens.name} — written by workbench; radius thickness n aperture-diameter (mm)"]
    for i, s in enumerate(lens.surfaces):
        if s.is_stop:
            r, n = 0.0, 0.0
        else:
            r = _DAT_FLAT_RADIUS_MM if s.curvature_per_mm == 0 else s.radius_mm
            n = s.material.nd
        last = i == len(lens.surfaces) - 1
        t = (lens.image_distance_mm or 0.0) if last else s.thickness_mm
        lines.append(f"{r:.10g}\t{t:.10g}\t{n:.10g}\t{2 * s.semi_aperture_mm:.10g}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- Zemax .zmx
def lens_from_zmx(text: str, name: str = "") -> Lens:
    """Zemax sequential file subset: SURF blocks with TYPE STANDARD/EVENASPH, CURV, DISZ, GLAS,
    DIAM (semi-diameter), STOP, CONI, PARM. The object surface (0) and the image surface are
    skipped; the gap before the image surface becomes the image distance. Glasses not in the
    catalogue use the n_d, V_d that the GLAS line carries."""
    blocks: list[dict] = []
    cur = None
    units = "MM"
    for lineno, raw in enumerate(text.splitlines(), 1):
        tok = raw.split()
        if not tok:
            continue
        key = tok[0].upper()
        if key == "UNIT" and len(tok) > 1:
            units = tok[1].upper()
        if key == "SURF":
            cur = {"type": "STANDARD", "curv": 0.0, "disz": 0.0, "glas": None, "diam": None,
                   "stop": False, "coni": 0.0, "parm": {}, "line": lineno}
            blocks.append(cur)
            continue
        if cur is None or not raw[:1].isspace():
            continue
        try:
            if key == "TYPE":
                cur["type"] = tok[1].upper()
            elif key == "CURV":
                cur["curv"] = float(tok[1])
            elif key == "DISZ":
                cur["disz"] = math.inf if tok[1].upper().startswith("INF") else float(tok[1])
            elif key == "GLAS":
                cur["glas"] = tok[1:]
            elif key == "DIAM":
                cur["diam"] = float(tok[1])
            elif key == "STOP":
                cur["stop"] = True
            elif key == "CONI":
                cur["coni"] = float(tok[1])
            elif key == "PARM":
                cur["parm"][int(tok[1])] = float(tok[2])
            elif key == "MIRR":
                raise ValueError("mirrors are not supported")
        except (IndexError, ValueError) as exc:
            raise ValueError(f"Zemax file line {lineno}: cannot read {raw.strip()!r} ({exc})") from None
    if units != "MM":
        raise ValueError(f"Zemax file: UNIT {units} not supported (only MM)")
    if len(blocks) < 3:
        raise ValueError("Zemax file: needs an object surface, at least one lens surface and an image surface")
    surfaces = []
    for b in blocks[1:-1]:
        if b["type"] not in ("STANDARD", "EVENASPH"):
            raise ValueError(f"Zemax surface at line {b['line']}: TYPE {b['type']} not supported "
                             "(allowed: STANDARD, EVENASPH)")
        med = AIR if b["glas"] is None else _zmx_glass(b["glas"], b["line"])
        coeffs = ()
        if b["type"] == "EVENASPH" and b["parm"]:
            coeffs = tuple(b["parm"].get(i, 0.0) for i in range(1, max(b["parm"]) + 1))
        if b["diam"] is None or b["diam"] <= 0:
            raise ValueError(f"Zemax surface at line {b['line']}: needs DIAM (semi-diameter) > 0")
        if not math.isfinite(b["disz"]):
            raise ValueError(f"Zemax surface at line {b['line']}: DISZ INFINITY inside the lens")
        surfaces.append(Surface(b["curv"], b["disz"], med, b["diam"], is_stop=b["stop"], conic=b["coni"],
                                asphere_coeffs=coeffs))
    last_t = surfaces[-1].thickness_mm
    return Lens(tuple(surfaces), name=name, image_distance_mm=last_t if last_t > 0 else None)


def _zmx_glass(fields: list[str], lineno: int):
    try:
        return material(fields[0])
    except ValueError:
        pass
    try:  # GLAS NAME code? ? nd vd ...
        nd, vd = float(fields[3]), float(fields[4])
        return material(f"{nd}/{vd}" if vd > 0 else f"{nd}")
    except (IndexError, ValueError):
        raise ValueError(f"Zemax file line {lineno}: glass {fields[0]!r} is not in the catalogue and the "
                         "GLAS line carries no n_d, V_d") from None
