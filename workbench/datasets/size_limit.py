"""How large a data set `workbench dataset` renders without being asked to confirm it: beyond
MAX_UNCONFIRMED_FRAMES frames the command refuses, with an estimate of the machine time, unless
--confirm-large is given (a typo of one digit should not start days of rendering)."""
from __future__ import annotations

from workbench.errors import ParameterError

MAX_UNCONFIRMED_FRAMES = 2000          # the standard profile's set is 600 frames (≥ 400 train, ≥ 200 test)
# one core, city_detection_quick at 320×240 and 100 spp: ~10 s a frame (measured); scaled by pixels × spp
# where the project's sampling adapts and render_estimate_s has no figure
SECONDS_PER_PIXEL_SAMPLE = 10.0 / (320 * 240 * 100)


def frame_estimate_s(project) -> float:
    """One frame's render time on one core (render_estimate_s, else the measured rate above at the
    project's max_spp)."""
    from workbench.render.city_frame import render_estimate_s
    est = render_estimate_s(project)
    if est is not None:
        return est
    spp = project.render.spp or project.render.max_spp
    return project.sensor.rows * project.sensor.cols * spp * SECONDS_PER_PIXEL_SAMPLE


def check_dataset_size(project, frames: int, workers: int, confirm_large: bool) -> None:
    """ParameterError naming --frames: beyond MAX_FRAMES always; with the estimated time, for more
    than MAX_UNCONFIRMED_FRAMES frames unless confirm_large."""
    from workbench.datasets.dataset import MAX_FRAMES
    if frames > MAX_FRAMES:                     # beyond what any run renders: said first, with or without the flag
        raise ParameterError("--frames", frames, f"an integer from 1 to {MAX_FRAMES:,}")
    if frames <= MAX_UNCONFIRMED_FRAMES or confirm_large:
        return
    cpu_h = frames * frame_estimate_s(project) / 3600
    wall = f", about {cpu_h / workers:,.1f} h on {workers} workers" if workers > 1 else ""
    raise ParameterError("--frames", frames, f"at most {MAX_UNCONFIRMED_FRAMES:,} frames unless confirmed "
                                             f"(--confirm-large): this set would take about {cpu_h:,.1f} h of CPU "
                                             f"time{wall}")
