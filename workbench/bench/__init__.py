"""Benchmarks: speed-versus-error measurements, run by `workbench bench NAME`.

Every benchmark lives in this package: a module per subject whose functions
`fn(args) -> BenchResult` register with `@register_bench(name)`; `all_benches()` imports every
module here and returns the registry. The command line prints a result's rows as a table (or JSON with
--json). Timing goes through workbench.bench.timing."""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from typing import Callable

from workbench.registry import Registry

MODULES = ("pipeline", "render", "optics", "isp", "sensor", "city", "lens_camera", "detect", "scale")
BENCHES: Registry[Callable] = Registry("bench", "benchmark")


@dataclass
class BenchResult:
    title: str
    rows: list[dict]
    notes: list[str] = field(default_factory=list)
    extra: dict = field(default_factory=dict)


def register_bench(name: str, help: str = ""):
    """Decorator: register `fn(args: argparse.Namespace) -> BenchResult` as `workbench bench name`."""
    def deco(fn):
        fn.bench_help = help
        return BENCHES.register(name)(fn)
    return deco


def all_benches() -> Registry[Callable]:
    """The registry with every benchmark module of this package imported."""
    for module in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{module.name}")
    return BENCHES


def format_table(result: BenchResult) -> str:
    """Plain-text table of a benchmark's rows (columns in first-row order)."""
    if not result.rows:
        return result.title + "\n(no rows)"
    cols = list(result.rows[0].keys())
    for r in result.rows[1:]:
        cols += [c for c in r if c not in cols]

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)
    cells = [[fmt(r.get(c, "")) for c in cols] for r in result.rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
    line = "  ".join(c.ljust(w) for c, w in zip(cols, widths))
    out = [result.title, line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(v.ljust(w) for v, w in zip(row, widths)) for row in cells]
    out += result.notes
    return "\n".join(out)
