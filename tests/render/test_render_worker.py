"""City renders in a worker process equal the ones made here; a camera move reuses the loaded
scene (and still equals a fresh render); cancelling stops the worker's render; a worker that dies
fails its job by name and the next job starts a new one."""
from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from workbench.errors import StageError
from workbench.jobs import CancelToken, JobCancelled, run_job
from workbench.project import load_project
from workbench.render.city_frame import CitySceneSession, city_scene_inputs, city_scene_job, frame_seeds
from workbench.render.render_worker import RenderWorker


def tiny_city(spp=4, **pose):
    p = load_project("city_paper_camera")
    p = p.updated(sensor=p.sensor.updated(rows=36, cols=48), render=p.render.updated(spp=spp),
                  city=p.city.updated(blocks_x=1, blocks_y=1, n_pedestrians=4, n_trees=4, n_lamps=4,
                                      n_benches=2, n_mailboxes=1))
    if pose:
        p = p.updated(pose=p.pose.updated(mode="manual", **pose))
    return p


def _same(a, b):
    assert np.array_equal(a.scene.radiance_photons, b.scene.radiance_photons)
    for key, value in a.labels.to_arrays().items():
        assert np.array_equal(value, b.labels.to_arrays()[key]), key


def test_a_camera_move_reuses_the_loaded_scene_and_renders_what_a_fresh_load_does():
    session = CitySceneSession()
    seeds = frame_seeds(0, 0)
    first = run_job(session.job(city_scene_inputs(tiny_city()), seeds))
    moved = tiny_city(manual_position_xy_m=(10.0, 2.0), manual_pan_deg=30.0)
    again = run_job(session.job(city_scene_inputs(moved), seeds))
    assert session.loads == 1                                    # the pose moved, the scene stayed
    _same(again, run_job(city_scene_job(city_scene_inputs(moved), seeds)))
    assert not np.array_equal(first.scene.radiance_photons, again.scene.radiance_photons)
    # A low-sample render of a move, then its full render: sample counts and seeds are
    # render-time settings, so both use the loaded scene, and each equals a fresh load's render.
    preview = moved.updated(pose=moved.pose.updated(manual_pan_deg=60.0),
                            render=moved.render.updated(spp=2, chunk_spp=2, preview_spp=2, seed=7))
    _same(run_job(session.job(city_scene_inputs(preview), seeds)),
          run_job(city_scene_job(city_scene_inputs(preview), seeds)))
    _same(run_job(session.job(city_scene_inputs(moved), seeds)), again)
    assert session.loads == 1
    run_job(session.job(city_scene_inputs(moved.updated(render=moved.render.updated(max_depth=3))), seeds))
    assert session.loads == 2                                    # anything else loads anew


def test_the_worker_renders_what_this_process_renders_and_cancels_and_recovers():
    worker = RenderWorker(threads=1)
    try:
        inputs, seeds = city_scene_inputs(tiny_city()), frame_seeds(0, 0)
        steps = []
        there = run_job(worker.job(inputs, seeds), steps.append)
        _same(there, run_job(city_scene_job(inputs, seeds)))
        assert steps and worker.pid != os.getpid()
        long = city_scene_inputs(tiny_city(spp=1 << 14).updated(
            render=tiny_city().render.updated(spp=1 << 14, chunk_spp=4)))
        cancel = CancelToken()
        job = worker.job(long, seeds, cancel)
        next(job)
        cancel.cancel()
        with pytest.raises(JobCancelled):
            for _ in job:
                pass
        pid = worker.pid
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(StageError, match="render worker process ended"):
            run_job(worker.job(inputs, seeds))
        _same(run_job(worker.job(inputs, seeds)), there)          # a new worker, the same image
        assert worker.pid != pid
    finally:
        worker.close()
    assert worker.pid is None


def test_a_job_left_half_way_frees_the_worker_for_the_next():
    """The window stops reading a render when a newer edit comes: the worker must drop that render
    and serve the next request, not read it as a cancel."""
    worker = RenderWorker(threads=1)
    try:
        seeds = frame_seeds(0, 0)
        slow = tiny_city().updated(render=tiny_city().render.updated(spp=1 << 14, chunk_spp=4))
        job = worker.job(city_scene_inputs(slow), seeds)
        next(job), next(job)
        job.close()                                  # the caller moved on
        quick = city_scene_inputs(tiny_city())
        _same(run_job(worker.job(quick, seeds)), run_job(city_scene_job(quick, seeds)))
    finally:
        worker.close()


def test_a_niced_worker_yields_the_cores_to_the_window():
    """The window's render worker runs niced (its render threads inherit it), so it can use every
    core while the GUI's threads still take one whenever they need it."""
    import time
    worker = RenderWorker(threads=1, nice=10)
    try:
        worker.start()
        mine = os.getpriority(os.PRIO_PROCESS, 0)
        deadline = time.monotonic() + 30
        while os.getpriority(os.PRIO_PROCESS, worker.pid) == mine and time.monotonic() < deadline:
            time.sleep(0.05)
        assert os.getpriority(os.PRIO_PROCESS, worker.pid) == min(mine + 10, 19)
    finally:
        worker.close()



def _binned(image, f=2):
    h, w = image.shape[:2]
    return image.reshape(h // f, f, w // f, f, -1).mean(axis=(1, 3))


def test_a_quick_look_samples_a_coarser_film_of_the_same_view_and_casts_visible_labels():
    import mitsuba as mi

    from workbench.render.city_frame import quick_look_factor
    f = quick_look_factor(48, 36)
    assert f == 2
    session = CitySceneSession()
    seeds = frame_seeds(0, 0)
    full = run_job(session.job(city_scene_inputs(tiny_city(spp=32)), seeds))
    quick = run_job(session.job(city_scene_inputs(tiny_city(spp=32)), seeds, quick_look=True))
    assert session.loads == 1 and quick.meta["render"]["coarse_factor"] == f
    q = quick.scene.radiance_photons
    assert q.shape == full.scene.radiance_photons.shape
    assert np.array_equal(q, np.repeat(np.repeat(_binned(q, f), f, axis=0), f, axis=1))   # f×f blocks
    # The same view: a point of the film (as a fraction of its size) gives the same camera ray
    # through the coarse pinhole as through the scene's own.
    fine, coarse = session._loaded[2].sensors()[0], session._coarse[1]
    uv = mi.Point2f(mi.Float([0.0, 0.25, 0.5, 1.0, 0.9]), mi.Float([0.0, 0.6, 0.5, 1.0, 0.1]))
    rays = [s.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))[0] for s in (fine, coarse)]
    assert np.allclose(np.asarray(rays[0].d), np.asarray(rays[1].d), atol=1e-6)
    assert np.allclose(np.asarray(rays[0].o), np.asarray(rays[1].o), atol=1e-6)
    assert abs(_binned(q, f).mean() / full.scene.radiance_photons.mean() - 1) < 0.03     # no bias
    # Labels: the first surface along each ray only, so the visible maps are the full pass's.
    assert quick.labels.meta["max_layers"] == 1
    for name in ("depth_m", "class_id", "instance_id"):
        assert np.array_equal(getattr(quick.labels, name), getattr(full.labels, name)), name
    assert {o.instance_id: o.bbox_xywh for o in quick.labels.objects if o.visible_px} == \
           {o.instance_id: o.bbox_xywh for o in full.labels.objects if o.visible_px}
    # A move points the coarse pinhole along the new pose, as it does the scene's.
    moved = run_job(session.job(city_scene_inputs(tiny_city(spp=2, manual_position_xy_m=(10.0, 2.0),
                                                            manual_pan_deg=30.0)), seeds, quick_look=True))
    assert session.loads == 1 and moved.meta["render"]["coarse_factor"] == f
    fine, coarse = session._loaded[2].sensors()[0], session._coarse[1]
    assert np.allclose(np.asarray(fine.world_transform().matrix), np.asarray(coarse.world_transform().matrix))
    # The worker passes the request on.
    worker = RenderWorker(threads=1)
    try:
        inputs = city_scene_inputs(tiny_city(spp=2))
        _same(run_job(worker.job(inputs, seeds, quick_look=True)),
              run_job(CitySceneSession().job(inputs, seeds, quick_look=True)))
    finally:
        worker.close()


def test_a_quick_look_samples_a_film_of_at_most_its_pixel_budget():
    """The coarse film of a quick look keeps its cost about constant: the smallest factor that
    divides both sides and leaves at most QUICK_LOOK_MAX_PIXELS pixels."""
    from workbench.render.city_frame import QUICK_LOOK_MAX_PIXELS, quick_look_factor
    assert [quick_look_factor(w, h) for w, h in ((48, 36), (320, 240), (640, 480), (1280, 960), (1920, 1080))] == \
           [2, 2, 4, 8, 8]
    for w, h in ((640, 480), (1920, 1080), (4000, 3000), (1000, 10)):
        f = quick_look_factor(w, h)
        assert w % f == 0 and h % f == 0 and (w // f) * (h // f) <= QUICK_LOOK_MAX_PIXELS
        assert all((w // g) * (h // g) > QUICK_LOOK_MAX_PIXELS for g in range(2, f) if w % g == 0 and h % g == 0)
    assert quick_look_factor(48, 35) == 1 and quick_look_factor(7, 7) == 7


def test_a_quick_look_of_an_odd_sized_film_samples_every_pixel():
    """A film whose side is not a multiple of the factor has no coarser film of exactly its view:
    the quick look then samples the film itself (its labels are still the visible ones)."""
    p = tiny_city(spp=1)
    p = p.updated(sensor=p.sensor.updated(rows=35, cols=48))
    quick = run_job(CitySceneSession().job(city_scene_inputs(p), frame_seeds(0, 0), quick_look=True))
    assert quick.meta["render"]["coarse_factor"] == 1 and quick.labels.meta["max_layers"] == 1
    assert quick.scene.radiance_photons.shape[:2] == (35, 48)


def test_results_through_shared_memory_equal_this_process_renders_and_leave_no_segment():
    """With every result through the worker's shared-memory segment (kept between frames, grown
    for a larger one), the frames equal this process's; closing the worker removes the segment."""
    worker = RenderWorker(threads=1, shared_min_bytes=0)
    seeds = frame_seeds(0, 0)
    small, moved = tiny_city(), tiny_city(manual_position_xy_m=(10.0, 2.0), manual_pan_deg=30.0)
    large = small.updated(sensor=small.sensor.updated(rows=72, cols=96))
    try:
        for project in (small, moved, large, small):
            inputs = city_scene_inputs(project)
            there = run_job(worker.job(inputs, seeds))
            _same(there, run_job(city_scene_job(inputs, seeds)))
            assert there.scene.radiance_photons.flags.writeable
        name = worker._inbox.segment.name
        assert worker._inbox.segment.size >= there.scene.radiance_photons.nbytes
    finally:
        worker.close()
    assert not os.path.exists(f"/dev/shm/{name.lstrip('/')}")
