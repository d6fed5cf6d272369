"""Sweep panel: a sweep runs to completion on a worker thread (thumbnails, chart); a sweep
cancelled mid-way leaves no partial results; editing the range is one 'experiment' edit."""
from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from workbench.gui.panels.sweep import SweepPanel
from workbench.pipeline import Pipeline
from workbench.project import load_project


@pytest.fixture(scope="module")
def frame():
    base = load_project("paper_camera")
    project = base.updated(sensor=base.sensor.updated(rows=120, cols=160))
    pipe = Pipeline(project)
    return project, pipe.signal_rate(), pipe.optical_image().wavelengths_nm


def make_panel(qtbot, frame):
    panel = SweepPanel()
    qtbot.addWidget(panel)
    panel.resize(800, 600)
    panel.show()
    qtbot.waitExposed(panel)
    panel.set_frame(*frame)
    return panel


def test_sweep_runs_to_completion(qtbot, grab, frame):
    panel = make_panel(qtbot, frame)
    panel.start.setValue(-4)
    panel.stop.setValue(4)
    panel.step.setValue(1)
    with qtbot.waitSignal(panel.sweep_finished, timeout=60_000):
        qtbot.mouseClick(panel.run_button, Qt.MouseButton.LeftButton)
    assert [p.ev for p in panel.results] == list(range(-4, 5))
    assert panel.thumbnails.count() == 9 and panel.progress.value() == 9
    qtbot.waitUntil(lambda: panel.run_button.isEnabled())
    qtbot.wait(50)
    assert len(np.unique(grab(panel.chart).reshape(-1, 3), axis=0)) > 20
    assert grab(panel.thumbnails).reshape(-1, 3).std(axis=0).max() > 10


def test_cancelled_sweep_leaves_no_partial_results(qtbot, frame):
    panel = make_panel(qtbot, frame)
    panel.step.setValue(0.25)                                   # 33 exposures
    # cancel from the panel's own progress, connected before the sweep starts (no race with its start)
    cancel_at_2 = (lambda v: v >= 2 and panel.cancel())
    panel.progress.valueChanged.connect(cancel_at_2)
    with qtbot.waitSignal(panel.sweep_cancelled, timeout=60_000):
        panel.run()
    panel.progress.valueChanged.disconnect(cancel_at_2)
    assert panel.results == [] and panel.thumbnails.count() == 0
    qtbot.waitUntil(lambda: panel.run_button.isEnabled())
    # a complete earlier sweep survives a later cancelled one unchanged
    panel.step.setValue(2)
    with qtbot.waitSignal(panel.sweep_finished, timeout=60_000):
        panel.run()
    kept = list(panel.results)
    qtbot.waitUntil(lambda: panel.run_button.isEnabled())
    panel.step.setValue(0.25)
    panel.progress.valueChanged.connect(cancel_at_2)
    with qtbot.waitSignal(panel.sweep_cancelled, timeout=60_000):
        panel.run()
    assert panel.results == kept and panel.thumbnails.count() == len(kept) == 5


def test_range_edit_emits_experiment_ev_biases(qtbot, frame):
    panel = make_panel(qtbot, frame)
    assert frame[0].experiment.ev_biases == [-4, -2, 0, 2, 4]
    assert (panel.start.value(), panel.stop.value(), panel.step.value()) == (-4, 4, 2)
    with qtbot.waitSignal(panel.edited) as sig:
        panel.step.setValue(1)
        panel.step.editingFinished.emit()
    assert sig.args == ["experiment", {"ev_biases": [-4, -3, -2, -1, 0, 1, 2, 3, 4]}]
