"""Lens files: ISETCam JSON (read/write), PBRT .dat (read/write), Zemax .zmx subset (read).

`load_lens(path)` also accepts the name of a lens in the lens library ("dgauss.50mm"): the lenses
shipped in resources/lenses/, then the user's own lenses (saved by the lens editor) in
`user_lens_dir()`. A project names its lens that way (optics.lens_file). Every
problem with a file is an InputFileError naming it; messages never echo the file's lines, and
every count or index read from a file is bounded before anything is allocated.
"""
from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path, PurePosixPath

from workbench.errors import InputFileError, InvalidValueError, OutputPathError
from workbench.files import atomic_write_text, parse_json, read_text
from workbench.optics.lens.glass import AIR, material
from workbench.optics.lens.model import Lens, Surface
from workbench.optics.lens.paraxial import paraxial, with_aperture_stop
from workbench.registry import Registry
from workbench.resource_dir import RESOURCES
from workbench.files import json_text

LENS_DIR = RESOURCES / "lenses"
# lens file readers by extension: reader(text, path, name) -> Lens; a new format registers here
LENS_READERS: Registry = Registry("optics.lens_file extension", "lens file format")
MAX_LENS_BYTES = 2 ** 20
MAX_SURFACES = 256
MAX_ASPHERE_TERMS = 16
MAX_INDEX_TABLE = 4096


USER_LENS_DIR_ENV = "WORKBENCH_LENS_DIR"


def user_lens_dir() -> Path:
    """The user's lens library: $WORKBENCH_LENS_DIR, else 'lenses' in the platform's user-data
    folder of camera-workbench (e.g. ~/.local/share/camera-workbench/lenses)."""
    env = os.environ.get(USER_LENS_DIR_ENV)
    if env:
        return Path(env)
    import platformdirs
    return Path(platformdirs.user_data_dir("camera-workbench")) / "lenses"


def lens_library() -> tuple[Path, ...]:
    """The folders lens names resolve in, in order: the shipped lenses, then the user's."""
    return LENS_DIR, user_lens_dir()


def available_lenses() -> list[str]:
    """Names of the lenses in the library (shipped ones first), without extension."""
    names: list[str] = []
    for folder in lens_library():
        if folder.is_dir():
            names += sorted(p.name[: -len(p.suffix)] for p in folder.iterdir()
                            if p.suffix in tuple(LENS_READERS) and p.name[: -len(p.suffix)] not in names)
    return names


def resolve_lens_path(path_or_name) -> Path:
    """A path to an existing lens file, or the library lens with that name."""
    p = Path(path_or_name)
    if os.path.lexists(p):
        return p
    return library_lens_path(str(path_or_name))


def library_lens_path(name: str) -> Path:
    """The file of a library lens (name relative to a library folder, with or without extension);
    InputFileError if there is none. Absolute names and '..' are refused."""
    rel = PurePosixPath(name.replace("\\", "/"))
    if not name or rel.is_absolute() or ".." in rel.parts:
        raise InputFileError(name, "a lens name is relative to the lens library (resources/lenses/ or "
                                   "the user's lens folder; no '..', not absolute)")
    for folder in lens_library():
        for ext in ("",) + tuple(LENS_READERS):
            q = folder / f"{rel}{ext}"
            try:
                if q.is_file():
                    return q
            except OSError:                 # a name too long for the file system, …: not a lens
                break
    raise InputFileError(name, f"no such lens file, and not a library lens (available: "
                               f"{', '.join(available_lenses())})")


def check_library_lens(name: str) -> None:
    """Raise InputFileError unless `name` is a library lens that reads without error and forms a
    real image (cached per file version), so that a project naming a missing, broken or
    non-imaging lens is refused when it loads."""
    p = library_lens_path(name)
    st = p.stat()
    _checked_lens(str(p), st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=64)
def _checked_lens(path: str, _mtime_ns: int, _size: int) -> None:
    from workbench.optics.lens.paraxial import imaging_problem
    problem = imaging_problem(load_lens(path))
    if problem is not None:
        raise InputFileError(path, f"cannot image: {problem} (`workbench lens info` shows its first-order values)")


def load_lens(path) -> Lens:
    """Read a lens by file extension: .json (ISETCam), .dat (PBRT), .zmx (Zemax subset).
    InputFileError (naming the file) if it cannot be read or is not a valid lens."""
    p = resolve_lens_path(path)
    ext = p.suffix.lower()
    text = read_text(p, "lens file", MAX_LENS_BYTES)          # a folder, no permission, … first
    if ext not in LENS_READERS:
        raise InputFileError(p, f"unknown lens file extension {ext!r}; allowed: {', '.join(LENS_READERS)}")
    name = p.name[: -len(p.suffix)]
    try:
        lens = LENS_READERS.get(ext)(text, p, name)
    except InputFileError:
        raise
    except (ValueError, TypeError, KeyError, IndexError, OverflowError, ZeroDivisionError) as exc:
        raise InputFileError(p, f"not a valid lens: {exc}") from None
    for i, s in enumerate(lens.surfaces):
        if not s.reaches_its_aperture:
            raise InputFileError(p, f"not a valid lens: surface {i}'s clear radius {s.semi_aperture_mm:g} mm lies "
                                    f"beyond where the surface (radius {s.radius_mm:g} mm, conic {s.conic:g}) is "
                                    "defined; a sphere's clear radius is at most |radius|")
    return lens


@LENS_READERS.register(".json")
def _read_json_lens(text: str, path: Path, name: str) -> Lens:
    return lens_from_json(parse_json(text, path, "lens file"), default_name=name)


@LENS_READERS.register(".dat")
def _read_dat_lens(text: str, path: Path, name: str) -> Lens:
    return lens_from_dat(text, name=name)


@LENS_READERS.register(".zmx")
def _read_zmx_lens(text: str, path: Path, name: str) -> Lens:
    return lens_from_zmx(text, name=name)


def _material(spec, where: str):
    try:
        return material(spec)
    except (ValueError, TypeError):
        raise InvalidValueError(f"{where}: the material is not a catalogue glass (resources/glass/), an index 'n' or "
                         "'n/V', or a [[wavelengths nm], [n]] table") from None


def _number(value, what: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidValueError(f"{where}: {what} must be a number")
    v = float(value)
    if not math.isfinite(v):
        raise InvalidValueError(f"{where}: {what} must be a finite number, got {v}")
    return v


def save_lens(lens: Lens, path) -> Path:
    """Write `lens` by extension (.json or .dat), atomically."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".json":
        text = json_text(lens_to_json(lens))
    elif ext == ".dat":
        text = lens_to_dat(lens)
    else:
        raise OutputPathError(p, f"a lens is saved as .json or .dat, not {ext!r}")
    atomic_write_text(p, text)
    return p


# ---------------------------------------------------------------- ISETCam JSON
def lens_from_json(data: dict, default_name: str = "") -> Lens:
    """ISETCam/iset3d lens JSON: surfaces of radius, thickness, ior (number or [[λ],[n]]),
    semi_aperture (mm); the stop has radius 0 and ior 0. Our extensions: 'glass' (a material spec),
    'is_stop', 'conic_constant', 'aspheric_coefficients' (r², r⁴ …), top-level 'image_distance_mm'."""
    if not isinstance(data, dict) or not isinstance(data.get("surfaces"), list):
        raise InvalidValueError("lens JSON: expected an object with a 'surfaces' list")
    if not 1 <= len(data["surfaces"]) <= MAX_SURFACES:
        raise InvalidValueError(f"lens JSON: {len(data['surfaces'])} surfaces; allowed 1–{MAX_SURFACES}")
    surfaces = []
    prev = AIR
    for i, s in enumerate(data["surfaces"]):
        where = f"lens JSON surface {i}"
        if not isinstance(s, dict) or not all(k in s for k in ("radius", "thickness", "semi_aperture")):
            raise InvalidValueError(f"{where}: needs numeric 'radius', 'thickness', 'semi_aperture'")
        radius = _number(s["radius"], "radius", where)
        thickness = _number(s["thickness"], "thickness", where)
        sa = s["semi_aperture"]
        if isinstance(sa, list) and 1 <= len(sa) <= 2:      # [x, y] semi-axes: circle of the larger
            sa = max(_number(v, "semi_aperture", where) for v in sa)
        sa = _number(sa, "semi_aperture", where)
        ior = s.get("ior", 1.0)
        is_stop = s.get("is_stop", radius == 0 and ior == 0 and "glass" not in s)
        if not isinstance(is_stop, bool):
            raise InvalidValueError(f"{where}: 'is_stop' must be true or false")
        if "glass" in s:
            med = _material(s["glass"], where)
        elif is_stop or ior == 0:
            med = prev
        elif isinstance(ior, list):
            if len(ior) != 2 or not all(isinstance(v, list) and len(v) <= MAX_INDEX_TABLE for v in ior):
                raise InvalidValueError(f"{where}: 'ior' table must be [[wavelengths nm], [n]] of at most "
                                 f"{MAX_INDEX_TABLE} entries")
            med = _material({"wavelength_nm": ior[0], "n": ior[1]}, where)
        else:
            med = _material(ior, where)
        coeffs = s.get("aspheric_coefficients", ()) or ()
        if not isinstance(coeffs, (list, tuple)) or len(coeffs) > MAX_ASPHERE_TERMS:
            raise InvalidValueError(f"{where}: 'aspheric_coefficients' must be a list of at most {MAX_ASPHERE_TERMS} "
                             "numbers")
        try:
            surf = Surface.from_radius(radius, thickness, med, sa, is_stop=is_stop,
                                       conic=_number(s.get("conic_constant", 0.0), "conic_constant", where),
                                       asphere_coeffs=tuple(_number(a, "aspheric coefficient", where)
                                                            for a in coeffs))
        except ValueError as exc:
            raise InvalidValueError(f"{where}: {exc}") from None
        surfaces.append(surf)
        prev = med
    d = data.get("image_distance_mm")
    meta = data.get("metadata", {})
    if not isinstance(meta, dict):
        raise InvalidValueError("lens JSON: 'metadata' must be an object")
    return with_aperture_stop(Lens(tuple(surfaces), name=str(data.get("name", default_name)),
                                   image_distance_mm=None if d is None else _number(d, "image_distance_mm",
                                                                                     "lens JSON"),
                                   description=str(data.get("description", "")), meta=dict(meta)))


def lens_to_json(lens: Lens) -> dict:
    """ISETCam-compatible JSON (ior = n_d, stop radius 0 / ior 0) with our exact-material extensions."""
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
        if len(surfaces) == MAX_SURFACES:
            raise InvalidValueError(f"PBRT lens: more than {MAX_SURFACES} surfaces")
        fields = line.split()
        try:
            r, t, n, diam = (float(v) for v in fields)
        except ValueError:
            raise InvalidValueError(f"PBRT lens line {lineno}: expected 4 numbers 'radius thickness n diameter' "
                             f"(found {len(fields)} field(s))") from None
        if not all(math.isfinite(v) for v in (r, t, n, diam)):
            raise InvalidValueError(f"PBRT lens line {lineno}: every number must be finite")
        stop = r == 0
        med = prev if stop or n == 0 else _material(n, f"PBRT lens line {lineno}")
        try:
            surfaces.append(Surface.from_radius(r, t, med, diam / 2.0, is_stop=stop))
        except ValueError as exc:
            raise InvalidValueError(f"PBRT lens line {lineno}: {exc}") from None
        prev = med
    if not surfaces:
        raise InvalidValueError("PBRT lens file has no surfaces")
    last_t = surfaces[-1].thickness_mm
    return with_aperture_stop(Lens(tuple(surfaces), name=name, image_distance_mm=last_t if last_t > 0 else None))


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
            if len(blocks) == MAX_SURFACES + 2:
                raise InvalidValueError(f"Zemax file: more than {MAX_SURFACES} surfaces")
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
                index = int(tok[1])
                if not 0 <= index <= MAX_ASPHERE_TERMS:
                    raise InvalidValueError(f"PARM index {index} outside 0–{MAX_ASPHERE_TERMS}")
                cur["parm"][index] = float(tok[2])
            elif key == "MIRR":
                raise InvalidValueError("mirrors are not supported")
        except (IndexError, ValueError) as exc:
            detail = str(exc) if str(exc).startswith(("PARM", "mirrors")) else "missing or non-numeric value"
            raise InvalidValueError(f"Zemax file line {lineno}: cannot read its {key} entry ({detail})") from None
        for k in ("curv", "diam", "coni"):
            if cur[k] is not None and not math.isfinite(cur[k]):
                raise InvalidValueError(f"Zemax file line {lineno}: {key} must be a finite number")
    if units != "MM":
        raise InvalidValueError("Zemax file: only UNIT MM is supported")
    if len(blocks) < 3:
        raise InvalidValueError("Zemax file: needs an object surface, at least one lens surface and an image surface")
    surfaces = []
    for b in blocks[1:-1]:
        if b["type"] not in ("STANDARD", "EVENASPH"):
            raise InvalidValueError(f"Zemax surface at line {b['line']}: its surface TYPE is not supported "
                             "(allowed TYPEs: STANDARD, EVENASPH)")
        med = AIR if b["glas"] is None else _zmx_glass(b["glas"], b["line"])
        coeffs = ()
        if b["type"] == "EVENASPH" and b["parm"]:
            coeffs = tuple(b["parm"].get(i, 0.0) for i in range(1, max(b["parm"]) + 1))
            if not all(math.isfinite(a) for a in coeffs):
                raise InvalidValueError(f"Zemax surface at line {b['line']}: PARM values must be finite")
        if b["diam"] is None or b["diam"] <= 0:
            raise InvalidValueError(f"Zemax surface at line {b['line']}: needs DIAM (semi-diameter) > 0")
        if not math.isfinite(b["disz"]):
            raise InvalidValueError(f"Zemax surface at line {b['line']}: DISZ INFINITY inside the lens")
        surfaces.append(Surface(b["curv"], b["disz"], med, b["diam"], is_stop=b["stop"], conic=b["coni"],
                                asphere_coeffs=coeffs))
    last_t = surfaces[-1].thickness_mm
    return with_aperture_stop(Lens(tuple(surfaces), name=name, image_distance_mm=last_t if last_t > 0 else None))


def _zmx_glass(fields: list[str], lineno: int):
    try:
        return material(fields[0])
    except (ValueError, IndexError):
        pass
    try:  # GLAS NAME code? ? nd vd ...
        nd, vd = float(fields[3]), float(fields[4])
    except (IndexError, ValueError):
        raise InvalidValueError(f"Zemax file line {lineno}: the glass is not in the catalogue (resources/glass/) and "
                         "the GLAS line carries no n_d, V_d") from None
    return _material(f"{nd}/{vd}" if vd > 0 else f"{nd}", f"Zemax file line {lineno}")
