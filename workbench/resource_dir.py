"""Where the shipped data (lenses, glass, sensor curves, sample projects) lives.

In a source checkout it is `resources/` beside the package; an installed wheel or a frozen app
carries the same tree as package data in `workbench/_resources/` (copied there by setup.py's
build step), read through importlib.resources so it works outside the source tree.
"""
from __future__ import annotations

import importlib.resources
from pathlib import Path


def _find_resources() -> Path:
    source_tree = Path(__file__).resolve().parent.parent / "resources"
    if (source_tree / "projects").is_dir():
        return source_tree
    packaged = Path(str(importlib.resources.files("workbench").joinpath("_resources")))
    if (packaged / "projects").is_dir():
        return packaged
    raise FileNotFoundError(f"the workbench's data folder is missing: looked in {source_tree} and "
                            f"{packaged}; reinstall the package")


RESOURCES: Path = _find_resources()
