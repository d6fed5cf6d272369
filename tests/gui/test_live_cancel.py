"""Cancel always works: a long city render in the live worker stops at the next chunk, emits no
frame, caches nothing half-done, and the worker takes the next edit."""
from __future__ import annotations

import time

from workbench.project import load_project


def slow_city_project():
    p = load_project("city_paper_camera")
    return p.updated(sensor=p.sensor.updated(rows=48, cols=64),
                     render=p.render.updated(spp=1 << 16, chunk_spp=4),     # minutes if not cancelled
                     city=p.city.updated(blocks_x=1, blocks_y=1, n_pedestrians=2, n_trees=2, n_lamps=2,
                                         n_benches=1, n_mailboxes=1))


def test_cancel_stops_a_long_render_and_the_worker_takes_the_next_edit(qapp, qtbot):
    from workbench.gui.live import LiveRunner
    runner = LiveRunner(preview_spp=1 << 16)         # no separate preview pass: one long render
    frames, messages = [], []
    runner.frameReady.connect(frames.append)
    runner.progress.connect(lambda msg, frac: messages.append((msg, frac)))
    try:
        project = slow_city_project()
        runner.submit(project)
        qtbot.waitUntil(lambda: any("spp" in m or "sample" in m for m, _ in messages), timeout=120_000)
        t0 = time.perf_counter()
        runner.cancel()
        qtbot.waitUntil(lambda: not runner.busy, timeout=30_000)
        stopped_s = time.perf_counter() - t0
        assert frames == []
        assert runner.pipeline.cached("scene", runner.pipeline.snapshot().keys["scene"]) is None
        assert stopped_s < 30
        quick = project.updated(render=project.render.updated(spp=2, chunk_spp=2))
        runner.submit(quick)
        qtbot.waitUntil(lambda: len(frames) == 1, timeout=120_000)
        assert frames[0].project == quick and frames[0].srgb.std() > 0
    finally:
        runner.shutdown()


def test_the_runner_warms_the_pixel_kernels_once_before_its_first_run(qapp, qtbot, monkeypatch):
    import workbench.warm_up
    from workbench.gui.live import LiveRunner
    warmed = []
    monkeypatch.setattr(workbench.warm_up, "warm_up_pixel_kernels", lambda p: warmed.append((p, len(frames))))
    runner = LiveRunner()
    frames = []
    runner.frameReady.connect(frames.append)
    try:
        project = load_project("paper_camera")
        project = project.updated(sensor=project.sensor.updated(rows=24, cols=32))
        runner.submit(project)
        qtbot.waitUntil(lambda: len(frames) == 1 and bool(warmed), timeout=60_000)
        runner.submit(project.updated(sensor=project.sensor.updated(analog_gain=2.0)))
        qtbot.waitUntil(lambda: len(frames) == 2 and not runner.busy, timeout=60_000)
        qtbot.wait(100)
        assert warmed == [(project, 0)]             # once, with the window's project, before the first frame
    finally:
        runner.shutdown()
