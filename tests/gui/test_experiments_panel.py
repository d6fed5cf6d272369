"""Experiments panel: opens result folders produced headless and draws both charts; runs a
command as a background process with parsed progress; Cancel kills the whole process tree."""
from __future__ import annotations

import json
import sys
import textwrap

import numpy as np
import psutil
import pytest

from workbench.gui.panels.experiments import ExperimentsPanel, parse_progress
from workbench.project import Project


def results_doc(kind: str) -> dict:
    if kind == "isp":
        summary = [{"net": "mobile", "representation": r, "condition": "ev0_trained", "test_ev": 0.0, "n": 3,
                    "mean_map": m, "sd": 0.02, "ci95_low": m - 0.05, "ci95_high": m + 0.05}
                   for r, m in (("raw", 0.41), ("linear", 0.52), ("srgb", 0.63))]
    else:
        summary = [{"net": "mobile", "representation": "srgb", "condition": c, "test_ev": ev, "n": 3,
                    "mean_map": 0.6 - 0.05 * abs(ev) + d, "sd": 0.02, "ci95_low": 0.55 - 0.05 * abs(ev) + d,
                    "ci95_high": 0.65 - 0.05 * abs(ev) + d}
                   for c, d in (("ev0_trained", 0.0), ("ev_mix", 0.02), ("per_ev", 0.05)) for ev in (-4, -2, 0, 2, 4)]
    names = ["raw − srgb", "linear − srgb"] if kind == "isp" else ["ev_mix − ev0_trained"] * 5
    evs = [0.0, 0.0] if kind == "isp" else [-4.0, -2.0, 0.0, 2.0, 4.0]
    contrasts = [{"contrast": n, "net": "mobile", "test_ev": ev, "mean": 0.02, "n": 3, "sd": 0.01, "t_low": 0.0,
                  "t_high": 0.04, "boot_low": -0.01, "boot_high": 0.05} for n, ev in zip(names, evs)]
    return {"format": "camera-workbench-experiment", "schema_version": 3, "kind": kind, "project": "city",
            "profile": "standard", "complete": True, "settings": {"seeds": 3}, "runs": [], "summary": summary,
            "contrasts": contrasts, "per_ev_is_upper_bound": True}


def make_panel(shown):
    panel = shown(ExperimentsPanel(), 900, 700)
    panel.set_project(Project())
    return panel


def test_output_split_across_reads_is_logged_as_whole_lines(qtbot, shown):
    panel = make_panel(shown)
    for chunk in ("PID-OF", "-CHILD", " 42\nisp:  0%| | 0/9\risp: 11%| | 1", "/9 [00:01]\rdone\n"):
        panel._take_output(chunk)
    assert panel.log.toPlainText().splitlines() == ["PID-OF-CHILD 42", "done"]
    assert (panel.progress.value(), panel.progress.maximum()) == (1, 9)


def test_parse_progress():
    assert parse_progress("isp:  33%|███▎      | 3/9 [00:05<00:10,  1.2s/run]") == (3, 9)
    assert parse_progress("\risp: 0%| | 0/9\risp: 11%|█ | 1/9 [00:01") == (1, 9)
    assert parse_progress("quick profile: 320×240 frames") is None


@pytest.mark.parametrize("kind", ["isp", "exposure"])
def test_opens_headless_result_folder_and_draws_chart(qtbot, grab, tmp_path, kind, shown):
    folder = tmp_path / "gpu-run" / f"experiment-{kind}"
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results_doc(kind)))
    panel = make_panel(shown)
    with qtbot.waitSignal(panel.results_shown):
        assert panel.open_folder(tmp_path / "gpu-run")          # finds the folder below
    assert panel.doc["kind"] == kind
    qtbot.waitUntil(panel.chart.is_current, timeout=120_000)   # a background chart render; slow only on a loaded machine
    pixels = grab(panel.chart).reshape(-1, 3)
    assert len(np.unique(pixels, axis=0)) > 50 and pixels.std(axis=0).max() > 20
    if kind == "isp":
        assert sorted(round(p.get_height(), 2) for p in panel.chart.figure().axes[0].patches) == [0.41, 0.52, 0.63]
    else:
        assert len([l for l in panel.chart.figure().axes[0].lines if len(l.get_xdata()) == 5]) == 3


def test_bad_folder_shows_the_error(qtbot, tmp_path, shown):
    panel = make_panel(shown)
    assert not panel.open_folder(tmp_path)
    assert "results.json" in panel.status.text() and panel.doc is None


FAKE_RUN = textwrap.dedent("""
    import json, sys, time, pathlib
    out = pathlib.Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
    doc = json.loads(sys.argv[2])
    for i in range(4):
        sys.stderr.write(f"\\risp: {25 * i}%| | {i}/3 [00:0{i}]"); sys.stderr.flush()
        time.sleep(0.1)
    (out / "results.json").write_text(json.dumps(doc))
""")


def test_runs_a_command_with_progress_and_shows_its_results(qtbot, tmp_path, shown):
    panel = make_panel(shown)
    out = tmp_path / "out"
    with qtbot.waitSignal(panel.run_finished, timeout=30_000) as sig:
        panel.run_argv([sys.executable, "-c", FAKE_RUN, str(out), json.dumps(results_doc("isp"))], out)
        assert panel.cancel_button.isEnabled() and not panel.run_button.isEnabled()
    assert sig.args == [0]
    assert panel.progress.maximum() == 1 and panel.progress.value() == 1
    assert panel.doc is not None and panel.doc["kind"] == "isp"
    assert "3/3" in panel.log.toPlainText()
    assert panel.run_button.isEnabled()


TREE = textwrap.dedent("""
    import subprocess, sys, time
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    print("PID-OF-CHILD", child.pid, flush=True)
    print("run 1/5", flush=True)
    time.sleep(120)
""")


def test_cancel_kills_the_process_tree(qtbot, tmp_path, shown):
    panel = make_panel(shown)
    panel.run_argv([sys.executable, "-c", TREE], tmp_path / "none")
    qtbot.waitUntil(lambda: "PID-OF-CHILD " in panel.log.toPlainText(), timeout=60_000)
    child = int(panel.log.toPlainText().split("PID-OF-CHILD ")[-1].split()[0])
    parent = panel._process.processId()
    assert psutil.pid_exists(child)
    with qtbot.waitSignal(panel.run_cancelled, timeout=20_000):
        panel.cancel()
    def gone(pid: int) -> bool:
        try:
            return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
        except psutil.NoSuchProcess:
            return True

    # the signals are sent at once; a loaded machine may take a moment to schedule the child's death
    qtbot.waitUntil(lambda: gone(child) and gone(parent), timeout=10_000)
    assert panel.doc is None and "cancelled" in panel.status.text()


def test_experiment_argv(qtbot, tmp_path, shown):
    panel = make_panel(shown)
    panel.kind.setCurrentText("exposure")
    panel.data_dir.setText(str(tmp_path / "data"))
    panel.out_dir.setText(str(tmp_path / "out"))
    argv = panel.experiment_argv("p.json")
    assert argv[1:] == ["-m", "workbench.cli", "experiment", "exposure", "p.json", "--data", str(tmp_path / "data"),
                        "--profile", "standard", "--out", str(tmp_path / "out")]


def test_the_real_experiment_command_is_started_on_the_shown_project(qtbot, tmp_path, monkeypatch, shown):
    """The panel's argv reaches `workbench experiment` (a missing data set fails fast, naming it)."""
    monkeypatch.chdir(tmp_path)
    panel = make_panel(shown)
    panel.data_dir.setText(str(tmp_path / "no-data"))
    with qtbot.waitSignal(panel.run_finished, timeout=120_000) as sig:
        panel.run_experiment()
    assert sig.args[0] != 0
    assert "no such data-set folder" in panel.log.toPlainText()
    assert "failed" in panel.status.text()
    assert panel.out_dir.text() == str(tmp_path / "experiment-isp-standard")


@pytest.mark.skipif(not hasattr(__import__("os"), "setpriority"), reason="no process niceness here")
def test_the_experiment_process_runs_below_the_windows_priority(qtbot, tmp_path, shown):
    import os

    from workbench.gui.panels.experiments import EXPERIMENT_NICE
    panel = make_panel(shown)
    script = "import os, time; time.sleep(0.5); print('NICE', os.nice(0), flush=True)"
    with qtbot.waitSignal(panel.run_finished, timeout=30_000):
        panel.run_argv([sys.executable, "-c", script], tmp_path / "none")
    niceness = int(panel.log.toPlainText().split("NICE ")[-1].split()[0])
    assert niceness == min(19, os.nice(0) + EXPERIMENT_NICE)
