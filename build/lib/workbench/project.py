"""The saved project: camera + scene + experiment set-up as one validated JSON document.

A project file is JSON with a format tag and a schema_version; it never holds code or pickles.
Loading validates every field and refuses a bad file with the field, the value and what is
allowed; saving is atomic (temporary file + rename), so a crash never leaves half a project.
"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError

from workbench.isp.params import ISPParams
from workbench.optics.params import OpticsParams
from workbench.params import Params
from workbench.render.params import RenderParams
from workbench.resource_dir import RESOURCES
from workbench.scene.city.recipe import CityRecipe, PoseParams
from workbench.scene.params import SceneParams
from workbench.sensor.params import SensorParams

FORMAT_TAG = "camera-workbench-project"
SCHEMA_VERSION = 1
PROJECTS_DIR = RESOURCES / "projects"


class ExperimentParams(Params):
    """Exposure-bias experiment (anchor: the paper's script): t = t_auto · 2^EV."""

    ev_biases: list[float] = Field(default_factory=lambda: [-4.0, -2.0, 0.0, 2.0, 4.0])
    auto_exposure_method: str = "mean"
    auto_exposure_level: float = Field(0.4, gt=0.0, le=1.0)
    mean_illuminance_lux: float = Field(1000.0, gt=0.0, le=1e7)


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


class ProjectError(ValueError):
    """A project file that cannot be used; the message says what to change."""


def _format_validation_error(exc: ValidationError, source: str) -> str:
    lines = [f"{source}: {exc.error_count()} invalid field(s):"]
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "(document)"
        given = err.get("input")
        given_txt = json.dumps(given, default=str)
        if len(given_txt) > 60:
            given_txt = given_txt[:57] + "..."
        lines.append(f"  {loc}: {err['msg']} (given: {given_txt})")
    return "\n".join(lines)


# Migrations from schema version N to N+1: functions dict -> dict. None yet (version 1).
MIGRATIONS: dict[int, callable] = {}


def project_from_dict(data: dict, source: str = "project") -> Project:
    """Validate a decoded project document (migrating older schema versions)."""
    if not isinstance(data, dict):
        raise ProjectError(f"{source}: a project file holds a JSON object, got {type(data).__name__}")
    if data.get("format") != FORMAT_TAG:
        raise ProjectError(f"{source}: not a workbench project (format must be '{FORMAT_TAG}', "
                           f"given {data.get('format')!r})")
    version = data.get("schema_version")
    if not isinstance(version, int) or version < 1:
        raise ProjectError(f"{source}: schema_version must be a positive integer, given {version!r}")
    if version > SCHEMA_VERSION:
        raise ProjectError(f"{source}: schema_version {version} was written by a newer workbench; "
                           f"this one reads up to {SCHEMA_VERSION} — update the workbench")
    while version < SCHEMA_VERSION:
        data = MIGRATIONS[version](dict(data))
        version = data["schema_version"]
    try:
        return Project.model_validate(data)
    except ValidationError as exc:
        raise ProjectError(_format_validation_error(exc, source)) from None


def resolve_project_path(path: str | os.PathLike) -> Path:
    """A path, or the name of a sample project in resources/projects (with or without .json)."""
    p = Path(path)
    if p.exists():
        return p
    for cand in (PROJECTS_DIR / p.name, PROJECTS_DIR / f"{p.name}.json"):
        if cand.exists():
            return cand
    samples = ", ".join(sorted(q.stem for q in PROJECTS_DIR.glob("*.json")))
    raise FileNotFoundError(f"no project file '{path}' (sample projects: {samples})")


def load_project(path: str | os.PathLike) -> Project:
    """Read and validate a project file; errors name the field and the allowed values."""
    p = resolve_project_path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ProjectError(f"{p}: not a text file (a project file is UTF-8 JSON)") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ProjectError(f"{p}: not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    return project_from_dict(data, str(p))


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write text to path atomically: a temporary file in the same folder, fsync, rename."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)          # mkstemp makes 0600; give the usual file mode
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def save_project(project: Project, path: str | os.PathLike) -> None:
    """Save atomically as indented JSON."""
    atomic_write_text(path, project.model_dump_json(indent=2) + "\n")
