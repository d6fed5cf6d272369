"""`workbench gui [PROJECT]`: open the window (needs the 'gui' extra and a display)."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    p = sub.add_parser("gui", help="open the workbench window on a project (default: the paper's camera)")
    p.add_argument("project", nargs="?", default=None, help="project file or sample name")
    p.set_defaults(func=cmd_gui)


def cmd_gui(args: argparse.Namespace) -> int:
    try:
        from workbench.gui.app import has_display, main
    except ModuleNotFoundError as exc:
        raise ValueError(f"the window needs the GUI packages ({exc.name} is missing): "
                         "pip install 'camera-workbench[gui]'") from None
    if not has_display():
        raise ValueError("no display (DISPLAY is not set): run the headless commands, e.g. "
                         "`workbench demo`, or start an X server")
    return main([args.project] if args.project else [])


def has_display_for_gui() -> bool:
    """True where `workbench` with no arguments should open the window (GUI packages + display)."""
    import importlib.util
    if importlib.util.find_spec("PySide6") is None:
        return False
    from workbench.gui.app import has_display
    return has_display()
