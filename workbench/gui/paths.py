"""Where the window keeps its own files: settings (window layout, recent files) and autosaves.

platformdirs' user folders for "camera-workbench"; WORKBENCH_GUI_HOME overrides both (tests)."""
from __future__ import annotations

import os
from pathlib import Path

APP_NAME = "camera-workbench"


def config_dir() -> Path:
    home = os.environ.get("WORKBENCH_GUI_HOME")
    if home:
        return Path(home) / "config"
    import platformdirs
    return Path(platformdirs.user_config_dir(APP_NAME))


def data_dir() -> Path:
    home = os.environ.get("WORKBENCH_GUI_HOME")
    if home:
        return Path(home) / "data"
    import platformdirs
    return Path(platformdirs.user_data_dir(APP_NAME))


def settings_file() -> Path:
    return config_dir() / "window.ini"


def autosave_dir() -> Path:
    return data_dir() / "autosave"
