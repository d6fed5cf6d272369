"""One error hierarchy for the whole workbench (DESIGN.md §3).

Every error a user can cause derives from WorkbenchError, so the command line prints one line and
exits non-zero, and the window can highlight the field a ParameterError names.

    WorkbenchError
    ├── ParameterError(field, given, allowed)   a value refused; names the field and what is allowed
    ├── InvalidValueError(message)              a value refused where there is no single field to name
    │                                           (an argument of a library function, an array shape)
    ├── InputFileError(path, problem)           a file that cannot be read or used (project, lens, CSV)
    ├── OutputPathError(path, problem)          a place results cannot be written
    └── StageError(stage, problem)              a simulation stage that cannot run on its input
"""
from __future__ import annotations

import os

import numpy as np


class WorkbenchError(Exception):
    """Base of every error the workbench raises on purpose; str() is one line a user can act on."""


class ParameterError(WorkbenchError, ValueError):
    """A parameter value that is refused: `field` (dotted path), the value `given`, what is `allowed`."""

    def __init__(self, field: str, given: object, allowed: str, source: str | None = None):
        self.field, self.given, self.allowed, self.source = field, given, allowed, source
        given_txt = repr(given)
        if len(given_txt) > 60:
            given_txt = given_txt[:57] + "..."
        prefix = f"{source}: " if source else ""
        super().__init__(f"{prefix}{field}: {allowed} (given: {given_txt})")

    def __reduce__(self):              # picklable, so an error raised in a worker process reaches the caller
        return type(self), (self.field, self.given, self.allowed, self.source)


class InvalidValueError(WorkbenchError, ValueError):
    """A value (an argument, an array's shape or range) the workbench refuses; the message says
    what was given and what is allowed. A ValueError too, so pydantic validators and callers that
    catch ValueError treat it as before; anything else raising ValueError is a bug, not bad input."""


class InputFileError(WorkbenchError, ValueError):
    """A file that cannot be read or used; the message names the file and never echoes its contents."""

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path, self.problem = str(path), problem
        super().__init__(f"{shown_name(self.path)}: {problem}")

    def __reduce__(self):
        return type(self), (self.path, self.problem)


MAX_SHOWN_NAME = 120


def shown_name(name: str) -> str:
    """A file or lens name as an error shows it: at most MAX_SHOWN_NAME characters (the middle
    elided), control characters replaced, so a hostile name cannot flood or forge a message."""
    clean = "".join(c if c.isprintable() else "?" for c in str(name))
    if len(clean) <= MAX_SHOWN_NAME:
        return clean
    half = (MAX_SHOWN_NAME - 1) // 2
    return f"{clean[:half]}…{clean[-half:]}"


class OutputPathError(WorkbenchError, OSError):
    """A place results cannot be written to (an existing file, a read-only folder, …)."""

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path, self.problem = str(path), problem
        super().__init__(f"{self.path}: {problem}")

    def __str__(self) -> str:          # OSError's own __str__ would show errno fields
        return f"{self.path}: {self.problem}"

    def __reduce__(self):
        return type(self), (self.path, self.problem)


class StageError(WorkbenchError, RuntimeError):
    """A simulation stage that cannot run on its input; names the stage."""

    def __init__(self, stage: str, problem: str):
        self.stage, self.problem = stage, problem
        super().__init__(f"stage '{stage}': {problem}")

    def __reduce__(self):
        return type(self), (self.stage, self.problem)


def check_finite(stage: str, array: np.ndarray) -> np.ndarray:
    """No NaN/Inf ever leaves a stage (DESIGN.md §3): raise StageError naming the stage, else return array."""
    if not np.all(np.isfinite(array)):
        bad = int(np.size(array) - np.count_nonzero(np.isfinite(array)))
        raise StageError(stage, f"produced {bad} NaN/Inf value(s); this is a bug or an input outside "
                                "the model's range — please report the project file")
    return array
