"""`workbench bench gui`: responsiveness of the window (GUI-thread stalls under background work,
edit-to-pane latency, 3-D view frames per second). The measuring code lives in workbench.gui.bench
(the only package that imports Qt); this module only registers it, importing nothing of Qt."""
from __future__ import annotations

from workbench.bench import BenchResult, register_bench


@register_bench("gui", help="window responsiveness: GUI stalls, edit-to-pane latency, 3-D fps")
def bench_gui(args) -> BenchResult:
    from workbench.gui.bench import run
    from workbench.gui.display import virtual_display
    import os
    import tempfile
    os.environ.setdefault("WORKBENCH_GUI_HOME", tempfile.mkdtemp(prefix="workbench-gui-home-"))  # fresh layout
    with virtual_display():
        out = run(quick=getattr(args, "quick", False))
        import shiboken6
        from PySide6.QtWidgets import QApplication
        shiboken6.delete(QApplication.instance())       # leave the X server before it stops
    return BenchResult("Window responsiveness (Xvfb + Mesa when no display)", out["rows"], out["notes"])
