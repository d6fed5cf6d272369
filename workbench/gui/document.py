"""The open project: the current Project, its file, unsaved state, undo history and autosave.

Every parameter edit is one QUndoCommand holding the whole previous and next Project (projects are
immutable), so undo gives back exactly the previous project and hence exactly the previous image.
Files go through workbench.project (validated load, atomic save). Unsaved edits are autosaved to
the user-data folder; a later session finds autosaves whose process is gone and offers them back.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtGui import QUndoCommand, QUndoStack

from workbench.errors import InputFileError, InvalidValueError, ParameterError, WorkbenchError
from workbench.files import atomic_write_text, pid_alive
from workbench.gui.paths import autosave_dir
from workbench.project import PROJECTS_DIR, Project, load_project, project_from_dict, save_project
from workbench.scene.city.recipe import CityRecipe, PoseParams

AUTOSAVE_INTERVAL_MS = 15_000
OPTIONAL_SECTIONS = {"city": CityRecipe, "pose": PoseParams}
LOAD_ERRORS = (WorkbenchError, OSError, ValueError)


def sample_projects() -> dict[str, Path]:
    """The shipped sample projects by name (resources/projects/*.json)."""
    return {p.stem: p for p in sorted(PROJECTS_DIR.glob("*.json"))}


def describe_edit(section: str, changes: dict) -> str:
    fields = ", ".join(f"{k} = {v!r}" for k, v in changes.items())
    return f"{section}: {fields}" if section else fields


def apply_edit(project: Project, section: str, changes: dict) -> Project:
    """A validated copy of project with `changes` applied to `section` ('' = top-level fields)."""
    if not section:
        return project.updated(**changes)
    current = getattr(project, section)
    if current is None:                     # optional sections start from their defaults
        current = OPTIONAL_SECTIONS[section]()
    return project.updated(**{section: current.updated(**changes)})


class _EditCommand(QUndoCommand):
    def __init__(self, doc: "Document", before: Project, after: Project, text: str):
        super().__init__(text)
        self._doc, self._before, self._after = doc, before, after

    def redo(self) -> None:
        self._doc._set_project(self._after)

    def undo(self) -> None:
        self._doc._set_project(self._before)


class Document(QObject):
    """projectChanged(Project) after every change; dirtyChanged(bool); pathChanged(str)."""

    projectChanged = Signal(object)
    dirtyChanged = Signal(bool)
    pathChanged = Signal(str)

    def __init__(self, project: Project | None = None, path: str | Path | None = None, parent=None,
                 autosave_interval_ms: int = AUTOSAVE_INTERVAL_MS):
        super().__init__(parent)
        self._project = project or Project()
        self._path = Path(path) if path else None
        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(self._clean_changed)
        self._autosave_file = autosave_dir() / f"session-{os.getpid()}-{id(self):x}.json"
        self._autosave_timer = QTimer(self)
        self._autosave_timer.setInterval(autosave_interval_ms)
        self._autosave_timer.timeout.connect(self.autosave)
        self._autosave_timer.start()

    # -- state -----------------------------------------------------------------------------
    @property
    def project(self) -> Project:
        return self._project

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def dirty(self) -> bool:
        return not self.undo_stack.isClean()

    @property
    def display_name(self) -> str:
        return self._path.name if self._path else self._project.name

    def _clean_changed(self, clean: bool) -> None:
        self.dirtyChanged.emit(not clean)

    def _set_project(self, project: Project) -> None:
        self._project = project
        self.projectChanged.emit(project)

    # -- edits -----------------------------------------------------------------------------
    def edit(self, section: str, changes: dict) -> None:
        """One undoable edit of `section`'s fields (raises the validation error, changing nothing)."""
        after = apply_edit(self._project, section, changes)
        if after == self._project:
            return
        self.undo_stack.push(_EditCommand(self, self._project, after, describe_edit(section, changes)))

    def replace(self, project: Project, text: str) -> None:
        """One undoable replacement of the whole project (e.g. a preset)."""
        if project != self._project:
            self.undo_stack.push(_EditCommand(self, self._project, project, text))

    # -- files -----------------------------------------------------------------------------
    def reset(self, project: Project, path: Path | None) -> None:
        """Start over on a project (New/Open): clear history, clean state."""
        self.discard_autosave()
        self._path = Path(path) if path else None
        self.undo_stack.clear()
        self.undo_stack.setClean()
        self._set_project(project)
        self.pathChanged.emit(str(self._path or ""))
        self.dirtyChanged.emit(False)

    def new_from_sample(self, name: str) -> None:
        samples = sample_projects()
        if name not in samples:
            raise ParameterError("sample", name, f"one of {', '.join(samples)}")
        self.reset(load_project(samples[name]), None)

    def open(self, path: str | Path) -> None:
        """Load a project file; a bad file raises (ProjectError …) and leaves everything as it was."""
        project = load_project(path)
        self.reset(project, Path(path))

    def save(self, path: str | Path | None = None) -> Path:
        target = Path(path) if path else self._path
        if target is None:
            raise InvalidValueError("the project has no file yet: use Save As")
        save_project(self._project, target)
        self._path = target
        self.undo_stack.setClean()
        self.discard_autosave()
        self.pathChanged.emit(str(target))
        return target

    # -- autosave and recovery -------------------------------------------------------------
    @property
    def autosave_file(self) -> Path:
        return self._autosave_file

    def autosave(self) -> Path | None:
        """Write the unsaved project (and where it came from) to the autosave folder."""
        if not self.dirty:
            return None
        record = {"pid": os.getpid(), "path": str(self._path) if self._path else None,
                  "project": json.loads(self._project.model_dump_json())}
        atomic_write_text(self._autosave_file, json.dumps(record) + "\n")
        return self._autosave_file

    def discard_autosave(self) -> None:
        self._autosave_file.unlink(missing_ok=True)

    def close(self) -> None:
        self._autosave_timer.stop()
        self.discard_autosave()

    def recover(self, autosave_file: Path) -> None:
        """Load an autosave as unsaved edits over its original file; the autosave file is removed."""
        record = json.loads(Path(autosave_file).read_text(encoding="utf-8"))
        if not isinstance(record, dict) or "project" not in record:
            raise InputFileError(autosave_file, "holds no project: not a workbench autosave")
        project = project_from_dict(record["project"], str(autosave_file))
        original = record.get("path")
        base = None
        if original and Path(original).exists():
            try:
                base = load_project(original)
            except LOAD_ERRORS:
                base = None
        self.reset(base or project, Path(original) if original else None)
        if base is not None:
            self.replace(project, "recovered unsaved edits")
        else:
            self.undo_stack.resetClean()
            self.dirtyChanged.emit(True)
        Path(autosave_file).unlink(missing_ok=True)


def set_aside(autosave_file: Path) -> Path:
    """Rename an autosave that cannot be recovered so it is never offered again; returns the new
    path (beside it, named rejected-…)."""
    autosave_file = Path(autosave_file)
    target = autosave_file.with_name(f"rejected-{autosave_file.name}")
    autosave_file.replace(target)
    return target


def find_recoverable() -> list[Path]:
    """Autosaves left by sessions whose process is gone (crashed or killed), newest first."""
    return scan_autosaves()[0]


def scan_autosaves() -> tuple[list[Path], list[tuple[Path, str]]]:
    """(autosaves left by sessions whose process is gone, newest first; (path, why) of the ones
    that cannot be read as an autosave: not JSON, truncated, empty, not an object, no session pid,
    a folder). A session writes its autosave whole (atomic replace), so a live session's file is
    never unreadable."""
    folder = autosave_dir()
    if not folder.is_dir():
        return [], []
    found, unreadable = [], []
    for f in folder.glob("session-*.json"):
        try:
            record = json.loads(f.read_text(encoding="utf-8"))
        except IsADirectoryError:
            unreadable.append((f, "a folder, not an autosave file"))
            continue
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            unreadable.append((f, f"not readable as JSON ({type(exc).__name__}: {exc})"))
            continue
        pid = record.get("pid") if isinstance(record, dict) else None
        if not isinstance(record, dict):
            unreadable.append((f, f"holds a JSON {type(record).__name__}, not an autosave record"))
        elif isinstance(pid, bool) or not isinstance(pid, int) or pid <= 0:
            unreadable.append((f, f"names no session process (pid {pid!r})"))
        elif not pid_alive(pid):
            found.append(f)
    return sorted(found, key=lambda f: f.stat().st_mtime, reverse=True), unreadable
