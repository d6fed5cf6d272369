"""Every tab of every dock can be shown at the sizes users run the window at (a sensor dock's 'QE
curves' tab once overflowed the stack in Qt's scroll-area layout and killed the window)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).with_name("visit_every_tab.py")


@pytest.mark.parametrize("width,height", [(1600, 1000), (1280, 800)])
def test_every_tab_of_every_dock_opens_without_a_crash(xserver, gui_home, width, height):
    env = {**os.environ, "WORKBENCH_GUI_HOME": str(gui_home)}
    proc = subprocess.run([sys.executable, str(SCRIPT), "paper_camera", str(width), str(height)],
                          capture_output=True, text=True, timeout=300, env=env)
    visited = [line for line in proc.stdout.splitlines() if line.startswith("visited")]
    assert proc.returncode == 0 and proc.stdout.rstrip().endswith("done"), (
        f"exit code {proc.returncode} after {visited[-1:] or 'no tab'}\n{proc.stderr[:2500]}")
    assert "visited dock Sensor / tab QE curves" in visited
    for dock in ("3-D city", "Lens", "Sensor", "ISP", "Exposure sweep", "Experiments"):
        assert f"visited dock {dock}" in visited
    assert len(visited) >= 16          # the 6 docks, 7 lens charts, 3 sensor tabs
