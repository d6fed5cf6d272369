"""The headless command line: `workbench <command> …` over the core the GUI will share."""
from __future__ import annotations

import argparse
import importlib
import logging
import sys

from workbench.errors import WorkbenchError
from workbench.files import json_text

# Modules under workbench.commands that add sub-commands; each has register(subparsers).
COMMAND_MODULES = ("core", "render", "lens", "selftest", "experiment", "sheet", "metrics")


def _bench(args: argparse.Namespace) -> int:
    from workbench.bench import BENCHES, format_table
    fn = BENCHES[args.name]
    if args.out is not None:
        from workbench.files import prepare_output_folder
        prepare_output_folder(args.out)
    result = fn(args)
    if args.json:
        print(json_text({"title": result.title, "rows": result.rows, "notes": result.notes,
                         **result.extra}, indent=2))
    else:
        print(format_table(result))
    return 0


def _can_open_window() -> bool:
    """The GUI packages are installed and there is a display (bare `workbench` opens the window)."""
    import importlib.util
    import os
    if importlib.util.find_spec("PySide6") is None:
        return False
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def _gui(args: argparse.Namespace) -> int:
    """`workbench gui [PROJECT]`: the window (Qt is imported only here, so the core runs without it)."""
    if not _can_open_window():
        raise WorkbenchError("the window needs the GUI packages (pip install 'camera-workbench[gui]') and a "
                             "display (DISPLAY is not set); without one, run the headless commands, e.g. "
                             "`workbench demo`")
    from workbench.gui.app import main as gui_main
    return gui_main([args.project] if args.project else [])


def build_parser() -> argparse.ArgumentParser:
    from workbench import __version__
    parser = argparse.ArgumentParser(prog="workbench", description=__doc__)
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(f"workbench.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"workbench.commands.{name}":
                continue
            raise
        mod.register(sub)
    gui = sub.add_parser("gui", help="open the workbench window on a project (default: the paper's camera)")
    gui.add_argument("project", nargs="?", default=None, help="project file or sample name")
    gui.set_defaults(func=_gui)
    from workbench.bench import all_benches
    bench = sub.add_parser("bench", help="speed-versus-error benchmarks (prints a table)")
    bench.add_argument("name", choices=sorted(all_benches()), help="which benchmark")
    bench.add_argument("--json", action="store_true", help="print the figures as JSON")
    bench.add_argument("--quick", action="store_true", help="small sizes and few repeats (CI)")
    bench.add_argument("--out", default=None, help="folder for plots the benchmark writes")
    bench.add_argument("--load", type=int, default=0,
                       help="busy processes (one core each) running during the measurement (gui: the CPU-hog case)")
    bench.set_defaults(func=_bench)
    return parser


def _one_line(exc: BaseException) -> str:
    """The error as one line: WorkbenchError messages are written so; others are collapsed."""
    if isinstance(exc, OSError) and not isinstance(exc, WorkbenchError) and exc.filename is not None:
        text = f"{exc.filename}: {exc.strerror or exc}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


def main(argv: list[str] | None = None) -> int:
    """Run one command. Errors a user can act on (WorkbenchError, a path the system refuses)
    print one line `workbench CMD: error: …` and return 2; any other exception is a bug: its
    traceback goes to the log, one line says so and names the log, and the exit code is 3."""
    from workbench.logs import setup_logging
    if not (sys.argv[1:] if argv is None else argv):    # bare `workbench`: the window, given a display
        if _can_open_window():
            argv = ["gui"]
    args = build_parser().parse_args(argv)
    log = setup_logging()
    logger = logging.getLogger("workbench.cli")
    logger.info("workbench %s", " ".join(sys.argv[1:] if argv is None else argv))
    command = " ".join(filter(None, (args.command, getattr(args, "lens_command", None))))
    try:
        return int(args.func(args) or 0)
    except (WorkbenchError, OSError) as exc:
        if getattr(exc, "is_bug", False):               # a job (compute.JobFailed) raised an unchecked error
            return _internal_error(command, exc, log, logger)
        logger.info("user error", exc_info=True)
        print(f"workbench {command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"workbench {command}: cancelled", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 — not bad input: a bug, reported as one
        return _internal_error(command, exc, log, logger)


def _internal_error(command: str, exc: BaseException, log, logger) -> int:
    """A bug: the traceback to the log, one line naming the log; exit code 3."""
    logger.error("internal error", exc_info=exc)
    where = f"; the traceback is in {log}" if log is not None else ""
    name = "" if getattr(exc, "is_bug", False) else f"{type(exc).__name__}: "
    print(f"workbench {command}: internal error (a bug, not your input): {name}{_one_line(exc)[:200]}{where}",
          file=sys.stderr)
    return 3


if __name__ == "__main__":
    sys.exit(main())
