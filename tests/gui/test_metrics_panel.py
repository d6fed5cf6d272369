"""Metrics panel: a frame's read-outs appear with it; an edit re-measures the design on a worker
(MTF, SNR, ΔE and their chart); pinning A and editing to B shows A, B and the change, and the
A | B | B − A strip; a burst of edits measures only the newest design after the running one."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.gui.live import FrameBuilder
from workbench.gui.panels.metrics import MetricsPanel
from workbench.pipeline import Pipeline
from workbench.project import load_project


@pytest.fixture(scope="module")
def small():
    base = load_project("paper_camera")
    return base.updated(sensor=base.sensor.updated(rows=120, cols=160))


def frame_of(project):
    return FrameBuilder().build(Pipeline(project), project, preview=False, submitted_at=0.0)


def make_panel(shown):
    return shown(MetricsPanel(), 700, 800)


def table(panel) -> dict[str, list[str]]:
    t = panel.table
    return {t.item(i, 0).text(): [t.item(i, j).text() for j in range(1, 5)] for i in range(t.rowCount())}


def test_readouts_measurements_and_a_b_comparison(qtbot, grab, small, shown):
    panel = make_panel(shown)
    frame = frame_of(small)
    with qtbot.waitSignal(panel.measured, timeout=180_000) as got:
        panel.set_project(small)
        panel.set_frame(frame)
    rows = table(panel)
    assert float(rows["exposure (ms)"][1]) == pytest.approx(1e3 * frame.readouts["exposure_s"], rel=1e-2)
    assert {"electrons R", "electrons G", "electrons B", "MTF50 sRGB (cy/px)", "ΔE2000 mean, held-out patches",
            "ΔE2000 mean, fitted (training) patches"} <= set(rows)
    assert got.args[0]["summary"]["mtf50_cy_px"] > 0 and got.args[0]["seconds"] > 0
    assert panel.table.isColumnHidden(1) and panel.table.isColumnHidden(3) and panel.table.isColumnHidden(4)
    qtbot.wait(50)
    assert len(np.unique(grab(panel.chart_views["mtf"]).reshape(-1, 3), axis=0)) > 20

    panel.pin()
    assert panel.changes.isVisible() and "no parameter differs" in panel.changes.text()
    b = small.updated(sensor=small.sensor.updated(pixel_pitch_um=1.5))
    with qtbot.waitSignal(panel.measured, timeout=180_000):
        panel.set_project(b)
        panel.set_frame(frame_of(b))
    rows = table(panel)
    assert panel.changes.text() == f"A → B: sensor.pixel_pitch_um {small.sensor.pixel_pitch_um} → 1.5"
    assert not panel.table.isColumnHidden(1) and not panel.table.isColumnHidden(3)
    a_nee, b_nee, change = (float(v) for v in rows["noise-equivalent exposure (mlx·s)"][:3])
    assert b_nee / a_nee == pytest.approx(4.0, rel=0.1) and change == pytest.approx(b_nee - a_nee, rel=1e-2)
    assert rows["noise-equivalent exposure (mlx·s)"][3] == "A better"        # beyond the measured uncertainty
    assert rows["sensor dynamic range (dB)"][3] == "same within ±0"         # a design parameter, unchanged
    assert rows["exposure (ms)"][3] == ""                                    # a frame read-out: no verdict
    panel.charts.setCurrentWidget(panel.ab)
    qtbot.waitUntil(lambda: panel.ab.pixmap() is not None and not panel.ab.pixmap().isNull(), timeout=20_000)
    assert len(np.unique(grab(panel.ab).reshape(-1, 3), axis=0)) > 50

    panel.clear_pin()
    assert panel.table.isColumnHidden(1) and panel.pinned is None and not panel.changes.isVisible()


def test_a_burst_of_edits_measures_the_newest_design_last(qtbot, small, shown):
    panel = make_panel(shown)
    designs = [small.updated(sensor=small.sensor.updated(read_noise_V=v)) for v in (0.001, 0.002, 0.003, 0.004)]
    seen = []
    panel.measured.connect(lambda m: seen.append(m["summary"]["read_noise_e"]))
    panel.set_project(designs[0])
    panel.measure()                                   # start now; the rest arrive while it runs
    for d in designs[1:]:
        panel.set_project(d)
        panel.measure()
    qtbot.waitUntil(lambda: bool(seen) and seen[-1] == pytest.approx(designs[-1].sensor.read_noise_e), timeout=90_000)
    qtbot.waitUntil(lambda: panel._worker is None, timeout=180_000)
    assert len(seen) <= 2                            # the first (if still current) and the newest only


def test_study_panel_runs_a_grid_resumes_it_and_draws_the_pareto_chart(qtbot, grab, small, tmp_path):
    from workbench.gui.panels.study import StudyPanel
    panel = StudyPanel()
    qtbot.addWidget(panel)
    panel.resize(700, 800)
    panel.show()
    qtbot.waitExposed(panel)
    panel.set_project(small)
    assert "optics.f_number" not in panel.grid.toPlainText()     # a pinhole's default varies what it reads
    panel.folder.setText(str(tmp_path / "study"))
    panel.grid.setPlainText("sensor.pixel_pitch_um=1.5,3\n\noptics.f_number=4")
    with qtbot.waitSignal(panel.finished, timeout=120_000) as got:
        panel.run()
    assert len(got.args[0]["designs"]) == 2 and panel.table.rowCount() == 2
    assert panel.notes.isVisible() and "irradiance" in panel.notes.text()   # the pinhole's f-number is flagged
    qtbot.wait(50)
    assert len(np.unique(grab(panel.chart).reshape(-1, 3), axis=0)) > 20
    with qtbot.waitSignal(panel.finished, timeout=180_000):            # the same grid: nothing measured again
        panel.run()
    assert "2 designs, 2 already measured" in panel.status.text() or "2 designs measured" in panel.status.text()
    qtbot.waitUntil(lambda: panel._worker is None, timeout=10_000)
    panel.grid.setPlainText("sensor.pixel_pitch_um")
    panel.run()
    assert "SECTION.FIELD" in panel.status.text() and panel._worker is None


def test_the_kept_side_process_outlives_the_thread_that_started_it():
    """The side process (camera metrics, EMVA) is started from a pool thread that Qt retires after 30 s idle; with
    Linux's parent-death signal (which follows that thread) the process died with it and the next
    measurement failed with BrokenProcessPool."""
    import os
    import threading
    import time

    from workbench.gui import side_process

    side_process.shutdown()
    pids = []
    starter = threading.Thread(target=lambda: pids.append(side_process.run(os.getpid)))
    starter.start()
    starter.join()
    time.sleep(1.0)                                   # the starting thread has ended
    assert side_process.run(os.getpid) == pids[0] != os.getpid()
    side_process.shutdown()


def test_the_side_process_is_warmed_with_a_measurement_and_a_running_one_counts_its_seconds(qtbot, shown, small):
    """The first measurement took 13 s (imports, kernels, caches) and showed only 'measuring…'; the
    window now measures its project once in the side process as it opens, and the status counts."""
    import os

    from workbench.gui import side_process
    metrics, _, _ = side_process.warm(small).result(timeout=300)
    assert metrics["project"] == small.name and metrics["summary"]["mtf50_cy_px"] > 0
    warmed = side_process.run(os.getpid)
    panel = make_panel(shown)
    panel.set_project(small)
    seen = []
    panel.measure(force=True)
    qtbot.waitUntil(lambda: seen.append(panel.status.text()) or panel._worker is None, timeout=300_000)
    assert any(t.startswith(f"measuring {small.name} on test charts… ") and t.endswith(" s") for t in seen)
    assert side_process.run(os.getpid) == warmed                   # the same, kept process measured it
