"""Benchmarks: speed-versus-error measurements, run by `workbench bench NAME`.

A benchmark is a function `fn(args) -> BenchResult` registered with `@register_bench(name)`;
the command line prints its rows as a table (or JSON with --json)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

BENCHES: dict[str, Callable] = {}


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
        BENCHES[name] = fn
        return fn
    return deco


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
