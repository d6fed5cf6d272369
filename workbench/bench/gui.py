"""`workbench bench gui`: responsiveness of the window (GUI-thread stalls under background work,
edit-to-pane latency, camera-move preview, 3-D view frames per second).

The measurement runs the real window in its own process (`python -m workbench.gui.bench`, on a
private Xvfb when there is no display): the benchmarks sit below the GUI and import none of it."""
from __future__ import annotations

import json
import subprocess
import sys

from workbench.bench import BenchResult, register_bench
from workbench.errors import StageError


@register_bench("gui", help="window responsiveness: GUI stalls, edit-to-pane latency, 3-D fps")
def bench_gui(args) -> BenchResult:
    cmd = [sys.executable, "-m", "workbench.gui.bench"] + (["--quick"] if getattr(args, "quick", False) else [])
    cmd += ["--load", str(int(getattr(args, "load", 0) or 0))]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise StageError("bench gui", f"the window benchmark failed (exit {done.returncode}): "
                                      f"{done.stderr.strip().splitlines()[-1] if done.stderr.strip() else ''}")
    out = json.loads(done.stdout.strip().splitlines()[-1])
    return BenchResult("Window responsiveness (Xvfb + Mesa when no display)", out["rows"], out["notes"])
