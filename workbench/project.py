"""The saved project: camera + scene + experiment set-up as one validated JSON document.

A project file is JSON with a format tag and a schema_version; it never holds code or pickles.
Loading refuses an unusable file with an InputFileError naming it and a bad value with a
ParameterError naming the dotted field, the value and what is allowed (workbench/errors.py).
Saving validates what it writes (no NaN or infinity; the written text must load back) and is
atomic (workbench/files.py).
"""
from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from workbench.errors import InputFileError, ParameterError
from workbench.files import atomic_write_text, parse_json, read_text
from workbench.isp.params import ISPParams
from workbench.optics.params import OpticsParams
from workbench.params import Params
from workbench.render.params import RenderParams
from workbench.resource_dir import RESOURCES
from workbench.scene.city.recipe import CityRecipe, PoseParams
from workbench.scene.params import SceneParams
from workbench.sensor.params import AutoExposureMethod, SensorParams

FORMAT_TAG = "camera-workbench-project"
SCHEMA_VERSION = 3
PROJECTS_DIR = RESOURCES / "projects"

EvBias = Annotated[float, Field(ge=-16.0, le=16.0)]


class ExperimentParams(Params):
    """Exposure-bias experiment (anchor: the paper's script): t = t_auto · 2^EV.

    The mean sensor illuminance of the experiment is scene.adjust_illuminance_lux (schema 1 had an
    unused experiment.mean_illuminance_lux; migration 1 → 2 drops it)."""

    ev_biases: list[EvBias] = Field(default_factory=lambda: [-4.0, -2.0, 0.0, 2.0, 4.0], min_length=1,
                                    max_length=64,
                                    description="exposure biases (EV, −16…16) of the sweep around auto-exposure")
    auto_exposure_method: AutoExposureMethod = Field("mean", description="auto-exposure method of the sweep")
    auto_exposure_level: float = Field(0.4, gt=0.0, le=1.0,
                                       description="auto-exposure target as a fraction of the swing")


class Project(Params):
    """The whole project document."""

    format: Literal["camera-workbench-project"] = FORMAT_TAG
    schema_version: int = SCHEMA_VERSION
    name: str = "untitled"
    description: str = ""
    seed: int = Field(0, ge=0, le=2**63 - 1,
                      description="master seed of data sets: frame i's city, pose and noise seeds derive from it")
    scene: SceneParams = SceneParams()
    city: CityRecipe | None = None
    pose: PoseParams | None = None
    optics: OpticsParams = OpticsParams()
    sensor: SensorParams = SensorParams()
    isp: ISPParams = ISPParams()
    render: RenderParams = RenderParams()
    experiment: ExperimentParams = ExperimentParams()

    @model_validator(mode="after")
    def _spectral_memory(self):
        """The spectral image's peak working memory (samples × wavelengths × ~24 bytes: the float32
        scene, the float64 optical image and one depth layer) stays under MAX_SPECTRAL_GIB; the
        pixel cap alone let 400 wavelengths × 2²⁵ pixels ask for 50 GiB."""
        gib = spectral_memory_gib(self)
        if gib > MAX_SPECTRAL_GIB:
            n = len(self.scene.wavelengths.grid()) if self.scene.kind != "city" else None
            raise ParameterError("sensor.rows/cols, scene.oversample, scene.wavelengths", f"{gib:.0f} GiB",
                                 f"a spectral image under {MAX_SPECTRAL_GIB} GiB of working memory: "
                                 f"{self.sensor.rows}×{self.sensor.cols} px × oversample {self.scene.oversample}² × "
                                 + (f"{n} wavelengths" if n else "the render's wavelengths")
                                 + "; use fewer pixels, a smaller oversample or a larger wavelength step")
        return self

    @model_validator(mode="after")
    def _focus_beyond_focal_length(self):
        """The object in focus (optics.focus_distance_m, else scene.distance_m) lies beyond the
        effective focal length, so the image is real; refused here instead of in the optics stage."""
        from workbench.optics.formation.lens_setup import effective_params
        f_mm = effective_params(self.optics).focal_length_mm
        field, distance_m = (("optics.focus_distance_m", self.optics.focus_distance_m)
                             if self.optics.focus_distance_m is not None else ("scene.distance_m", self.scene.distance_m))
        if not distance_m * 1e3 > f_mm:
            raise ParameterError(field, distance_m, f"must exceed the effective focal length ({f_mm:.4g} mm) for "
                                                    "a real image")
        return self

    @model_validator(mode="after")
    def _rectilinear_field_of_view(self):
        """The sensor behind the optics spans less than MAX_FIELD_OF_VIEW_DEG (a focal length of
        10⁻³⁰⁰ mm made the scene 180° wide, refused by the scene without naming a setting)."""
        from workbench.optics.formation.lens_setup import effective_params
        from workbench.optics.params import fov_deg
        if self.scene.fov_deg is not None:
            return self
        f_mm = effective_params(self.optics).focal_length_mm
        width_mm = self.sensor.cols * self.sensor.pixel_pitch_um * 1e-3
        hfov = fov_deg(f_mm, width_mm)
        if not hfov < MAX_FIELD_OF_VIEW_DEG:
            field, value = (("optics.lens_file", self.optics.lens_file) if self.optics.lens_file is not None
                            and not self.optics.scale_lens_to_focal_length else ("optics.focal_length_mm", f_mm))
            raise ParameterError(field, value, f"a {f_mm:.4g} mm focal length spans {hfov:.6g}° across the sensor's "
                                               f"{width_mm:.4g} mm width; a rectilinear camera images less than "
                                               f"{MAX_FIELD_OF_VIEW_DEG:g}°: use a longer focal length or a narrower "
                                               "sensor (sensor.cols × sensor.pixel_pitch_um)")
        return self


MAX_SPECTRAL_GIB = 16.0
MAX_FIELD_OF_VIEW_DEG = 179.0
BYTES_PER_SPECTRAL_SAMPLE = 24


def spectral_memory_gib(project: Project) -> float:
    """Estimated peak memory (GiB) of the project's spectral image (see Project._spectral_memory);
    a city counts the render's output grid over 300–1,100 nm at render.output_step_nm (an upper bound)."""
    if project.scene.kind == "city":
        bands = int(np.ceil(800.0 / project.render.output_step_nm)) + 1
    else:
        bands = len(project.scene.wavelengths.grid())
    samples = project.sensor.rows * project.sensor.cols * project.scene.oversample ** 2
    return samples * bands * BYTES_PER_SPECTRAL_SAMPLE / 2 ** 30


# Pydantic's tags of union members in an error location ('float', 'list[list[float]]'): not fields.
_TYPE_TAGS = {"float", "int", "str", "bool", "none", "bytes", "list", "tuple", "dict", "set"}


def _field_path(loc: tuple) -> str:
    parts = []
    for part in loc:
        if isinstance(part, str) and ("[" in part or part in _TYPE_TAGS):
            continue
        text = str(part)
        parts.append(text if text.isprintable() and text else repr(text))
    return ".".join(parts) or "(document)"


def parameter_error(exc: ValidationError, source: str | None = None, prefix: str = "") -> ParameterError:
    """The first error of a pydantic ValidationError as a ParameterError naming its dotted field
    (after `prefix`); the others are counted and named in the message."""
    errors = exc.errors()
    first = errors[0]
    field = _field_path(((prefix,) if prefix else ()) + tuple(first["loc"]))
    allowed = first["msg"].removeprefix("Value error, ").removeprefix("Assertion failed, ")
    if allowed.startswith("Input should be "):           # pydantic's wording → ours ("must be a finite number")
        allowed = "must be " + allowed.removeprefix("Input should be ")
    given = first.get("input")
    cause = (first.get("ctx") or {}).get("error")
    if isinstance(cause, ParameterError):        # raised by a validator: its field may be absolute
        if field == "(document)":                  # ('isp.demosaic') or relative to the location
            field = cause.field
        elif field.split(".")[-1] != cause.field.split(".")[-1]:
            field = f"{field}.{cause.field}"
        given, allowed = cause.given, cause.allowed
    others = sorted({_field_path(((prefix,) if prefix else ()) + tuple(e["loc"])) for e in errors[1:]} - {field})
    if others:
        shown = ", ".join(others[:4]) + (", …" if len(others) > 4 else "")
        allowed = f"{allowed} [also invalid: {shown}]"
    return ParameterError(field, given, " ".join(allowed.split()), source)


def _drop_mean_illuminance_lux(data: dict) -> dict:
    """1 → 2: experiment.mean_illuminance_lux was never read (scene.adjust_illuminance_lux sets the
    illuminance), so dropping it keeps every result."""
    experiment = data.get("experiment")
    if isinstance(experiment, dict):
        data["experiment"] = {k: v for k, v in experiment.items() if k != "mean_illuminance_lux"}
    return data | {"schema_version": 2}


def _add_scene_world(data: dict) -> dict:
    """2 → 3: render.world (day/night, fog, glass) and render.daylight.sky_model are new; their
    defaults (day, clear air, diffuse glass, uniform sky) are what version 2 rendered, so a
    version-2 file keeps every result. (The version marks files an older workbench cannot read.)"""
    return data | {"schema_version": 3}


# Migrations from schema version N to N+1 (decoded document → decoded document).
MIGRATIONS: dict[int, Callable[[dict], dict]] = {1: _drop_mean_illuminance_lux, 2: _add_scene_world}


def project_from_dict(data: object, source: str | None = None) -> Project:
    """Validate a decoded project document (migrating older schema versions).

    Raises InputFileError if it is not a project document at all, ParameterError naming the field
    otherwise."""
    where = source or "project"
    if not isinstance(data, dict):
        raise InputFileError(where, f"a project file holds a JSON object, not a {type(data).__name__}")
    if data.get("format") != FORMAT_TAG:
        raise ParameterError("format", data.get("format"), f"must be '{FORMAT_TAG}' (is this a workbench "
                                                          "project file?)", source)
    version = data.get("schema_version")
    if type(version) is not int or version < 1:
        raise ParameterError("schema_version", version, "must be a positive integer", source)
    if version > SCHEMA_VERSION:
        raise ParameterError("schema_version", version, f"written by a newer workbench; this one reads up to "
                                                        f"{SCHEMA_VERSION} — update the workbench", source)
    while version < SCHEMA_VERSION:
        data = MIGRATIONS[version](dict(data))
        version = data["schema_version"]
    try:
        return Project.model_validate_json(json.dumps(data))
    except ValidationError as exc:
        raise parameter_error(exc, source) from None


def resolve_project_path(path: str | os.PathLike) -> Path:
    """A path, or the name of a sample project in resources/projects (with or without .json)."""
    p = Path(path)
    if os.path.lexists(p):
        return p
    if p.name == str(path):
        for cand in (PROJECTS_DIR / p.name, PROJECTS_DIR / f"{p.name}.json"):
            try:
                if cand.is_file():
                    return cand
            except OSError:                 # a name too long for the file system, …: no sample
                break
    samples = ", ".join(sorted(q.stem for q in PROJECTS_DIR.glob("*.json")))
    raise InputFileError(p, f"no such project file (sample projects: {samples})")


def load_project(path: str | os.PathLike) -> Project:
    """Read and validate a project file: InputFileError for a file that cannot be read or decoded,
    ParameterError naming the field for a bad value."""
    p = resolve_project_path(path)
    return project_from_dict(parse_json(read_text(p, "project file"), p, "project file"), str(p))


def _non_finite_field(node: object, path: str = "") -> tuple[str, float] | None:
    if isinstance(node, float) and not math.isfinite(node):
        return path or "(document)", node
    if isinstance(node, dict):
        items = ((f"{path}.{k}" if path else str(k), v) for k, v in node.items())
    elif isinstance(node, (list, tuple)):
        items = ((f"{path}.{i}", v) for i, v in enumerate(node))
    else:
        return None
    for sub, value in items:
        found = _non_finite_field(value, sub)
        if found:
            return found
    return None


def project_to_json(project: Project) -> str:
    """The project as indented JSON, validated: a NaN or infinity anywhere is refused (JSON has no
    such numbers; `null` would reload as a different value) and the text must load back."""
    data = project.model_dump(mode="json")
    bad = _non_finite_field(data)
    if bad:
        raise ParameterError(bad[0], bad[1], "must be a finite number (a project file cannot store NaN or "
                                             "infinity)")
    text = json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
    project_from_dict(json.loads(text))
    return text


def save_project(project: Project, path: str | os.PathLike) -> Path:
    """Validate and save atomically as indented JSON (see atomic_write_text); returns the file written."""
    return atomic_write_text(path, project_to_json(project))


def project_differences(a: Project, b: Project, skip: tuple[str, ...] = ("name", "description")) -> list[tuple]:
    """(dotted field, value in a, value in b) of every parameter where two projects differ (the
    leaves of their JSON form; a section set in one and absent in the other is one entry), fields
    starting with one of `skip` left out."""
    out: list[tuple] = []

    def walk(x, y, prefix: str) -> None:
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                walk(x.get(k), y.get(k), f"{prefix}.{k}" if prefix else k)
        elif x != y and not prefix.startswith(skip):
            out.append((prefix, x, y))
    walk(json.loads(a.model_dump_json()), json.loads(b.model_dump_json()), "")
    return out


def difference_labels(a: Project, b: Project, max_fields: int = 2) -> tuple[str, str]:
    """Short names of two designs by what differs ('A: pixel_pitch_um 3', 'B: pixel_pitch_um 1.5'):
    the first `max_fields` parameters project_differences finds (their last name, values as given),
    '+N more' beyond; the project names when no parameter differs (both 'A'/'B' and the name, with
    '(same design)' on B when the names agree too)."""
    diff = project_differences(a, b)
    if not diff:
        return f"A: {a.name}", f"B: {b.name}" + (" (same design)" if a.name == b.name else "")

    def name(side: int) -> str:
        shown = [f"{field.rsplit('.', 1)[-1]} {_short(values[side])}" for field, *values in diff[:max_fields]]
        more = len(diff) - max_fields
        return ", ".join(shown) + (f" +{more} more" if more > 0 else "")
    return "A: " + name(0), "B: " + name(1)


def _short(value) -> str:
    """A parameter value for a label: numbers in %g, a file or a long text by its last part."""
    if isinstance(value, float):
        return f"{value:g}"
    text = str(value)
    return text.rsplit("/", 1)[-1] if len(text) > 24 else text
