"""The headless command line: `workbench <command> …` over the core the GUI will share."""
from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys

# Modules under workbench.commands that add sub-commands; each has register(subparsers).
COMMAND_MODULES = ("core", "render", "lens", "selftest")
# Modules that register benchmarks when imported.
BENCH_MODULES = ("workbench.bench.pipeline", "workbench.bench.render", "workbench.bench.optics",
                 "workbench.isp.bench", "workbench.sensor.bench", "workbench.bench.city",
                 "workbench.optics.lens.bench")


def _bench(args: argparse.Namespace) -> int:
    from workbench.bench import BENCHES, format_table
    fn = BENCHES[args.name]
    result = fn(args)
    if args.json:
        print(json.dumps({"title": result.title, "rows": result.rows, "notes": result.notes,
                          **result.extra}, indent=2, default=float))
    else:
        print(format_table(result))
    return 0


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
    from workbench.bench import BENCHES
    for modname in BENCH_MODULES:
        try:
            importlib.import_module(modname)
        except ModuleNotFoundError as exc:
            if exc.name != modname:
                raise
    bench = sub.add_parser("bench", help="speed-versus-error benchmarks (prints a table)")
    bench.add_argument("name", choices=sorted(BENCHES), help="which benchmark")
    bench.add_argument("--json", action="store_true", help="print the figures as JSON")
    bench.add_argument("--quick", action="store_true", help="small sizes and few repeats (CI)")
    bench.add_argument("--out", default=None, help="folder for plots the benchmark writes")
    bench.set_defaults(func=_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    from workbench.logs import setup_logging
    args = build_parser().parse_args(argv)
    setup_logging()
    logging.getLogger("workbench.cli").info("workbench %s", " ".join(sys.argv[1:] if argv is None else argv))
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"workbench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"workbench {args.command}: cancelled", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
