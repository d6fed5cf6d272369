"""`workbench bench pipeline`: median time of every stage and peak memory at 640×480 and 1280×960.

The live-preview budget is the sensor + ISP on a cached optical image (16 wavelength bands):
pixel signal + exposure/noise/ADC + demosaic/colour/sRGB must take ≤ 30 ms at 640×480. The
window's goals (issue 17) for a sensor edit at 640×480: exposure/noise/ADC + bilinear ISP ≤ 10 ms,
with the Malvar demosaic ≤ 25 ms (the `sensor` and `isp` columns summed).
"""
from __future__ import annotations

import resource
import tracemalloc

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import median_times_ms

LIVE_PREVIEW_BUDGET_MS = 30.0
SENSOR_ISP_GOAL_MS = 10.0
SENSOR_MALVAR_GOAL_MS = 25.0


def _times(name: str, fn, repeats: int) -> dict:
    """The columns `name`_ms (median wall) and `name`_cpu_ms (median process CPU, all threads:
    the figure to compare runs by on a shared machine)."""
    wall, cpu = median_times_ms(fn, repeats)
    return {f"{name}_ms": wall, f"{name}_cpu_ms": cpu}


def bench_resolution(rows: int, cols: int, repeats: int, bands_step_nm: float = 20.0) -> dict:
    """Stage medians (ms) for the paper's camera on the Macbeth chart at rows×cols."""
    from workbench.isp import sensor_image_to_srgb
    from workbench.project import load_project
    from workbench.sensor import irradiance_to_signal_rate, resolve_exposure, signal_rate_to_sensor_image
    from workbench.stages.geometry import project_geometry
    from workbench.stages.optics import form_optical_image
    from workbench.stages.scene import chart_scene

    base = load_project("paper_camera")
    # Same field of view at every resolution: the pixel shrinks as the count grows.
    pitch = base.sensor.pixel_pitch_um * base.sensor.cols / cols
    project = base.updated(
        sensor=base.sensor.updated(rows=rows, cols=cols, pixel_pitch_um=pitch),
        scene=base.scene.updated(kind="macbeth", wavelengths=base.scene.wavelengths.updated(step_nm=bands_step_nm)))

    def make_scene():
        return chart_scene(project.scene, project_geometry(project))

    def make_optical_image(scene):
        return form_optical_image(scene, project.optics, project_geometry(project),
                                  project.scene.adjust_illuminance_lux)
    scene = make_scene()
    oi = make_optical_image(scene)
    rate = irradiance_to_signal_rate(oi, project.sensor)
    rng = np.random.default_rng(0)
    sensor, wl = project.sensor, oi.wavelengths_nm

    def capture(rate):
        return signal_rate_to_sensor_image(rate, sensor, resolve_exposure(rate, sensor), rng, wavelengths_nm=wl)
    image = capture(rate)
    malvar = project.isp.updated(demosaic="malvar2004")

    def live():
        sensor_image_to_srgb(capture(irradiance_to_signal_rate(oi, sensor)), project.isp)

    tracemalloc.start()
    sensor_image_to_srgb(capture(irradiance_to_signal_rate(make_optical_image(make_scene()), sensor)), project.isp)
    peak_bytes = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()

    heavy = max(1, repeats // 4)
    return {
        "resolution": f"{cols}x{rows}",
        "bands": int(oi.wavelengths_nm.size),
        **_times("scene", make_scene, heavy),
        **_times("optics", lambda: make_optical_image(scene), heavy),
        **_times("signal", lambda: irradiance_to_signal_rate(oi, sensor), repeats),
        **_times("sensor", lambda: capture(rate), repeats),
        **_times("isp", lambda: sensor_image_to_srgb(image, project.isp), repeats),
        **_times("isp_malvar2004", lambda: sensor_image_to_srgb(image, malvar), repeats),
        **_times("sensor+isp_from_cached_irradiance", live, repeats),
        "peak_traced_MB": peak_bytes / 2**20,
    }


@register_bench("pipeline", help="stage times and peak memory of the core pipeline")
def bench_pipeline(args) -> BenchResult:
    repeats = 5 if getattr(args, "quick", False) else 21
    sizes = [(480, 640)] if getattr(args, "quick", False) else [(480, 640), (960, 1280)]
    rows = [bench_resolution(r, c, repeats) for r, c in sizes]
    live = rows[0]["sensor+isp_from_cached_irradiance_ms"]
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    verdict = "within" if live <= LIVE_PREVIEW_BUDGET_MS else "OVER"
    first = rows[0]
    sensor_isp = first["sensor_ms"] + first["isp_ms"]
    sensor_malvar = first["sensor_ms"] + first["isp_malvar2004_ms"]
    notes = [f"live preview (sensor + ISP from cached 16-band irradiance, 640x480): {live:.1f} ms median "
             f"— {verdict} the {LIVE_PREVIEW_BUDGET_MS:.0f} ms budget",
             f"sensor + bilinear ISP: {sensor_isp:.1f} ms (goal {SENSOR_ISP_GOAL_MS:.0f}); sensor + Malvar ISP: "
             f"{sensor_malvar:.1f} ms (goal {SENSOR_MALVAR_GOAL_MS:.0f}); 640x480, medians of wall time",
             f"process peak RSS: {rss_mb:.0f} MB; medians of {repeats} runs (heavy stages {max(1, repeats // 4)})",
             "*_ms = wall time, *_cpu_ms = process CPU time of all threads (compare runs by it on a shared machine)"]
    return BenchResult("bench pipeline: median stage times (ms), paper camera, Macbeth chart", rows, notes,
                       extra={"peak_rss_MB": rss_mb, "live_preview_ms": live,
                              "live_preview_budget_ms": LIVE_PREVIEW_BUDGET_MS, "sensor_isp_ms": sensor_isp,
                              "sensor_malvar_ms": sensor_malvar})
