"""Render noise of a data set against the sensor's shot noise: is the Monte-Carlo noise baked into
the stored irradiance small beside the photon noise the experiments study?

For a few frames of a `workbench dataset` folder, the frame is rendered again from its own seeds
with `reference_spp` samples (multijitter, independent of the stored render), both are turned into
the experiment sensor's mean electron rate per pixel, and every pixel's render error
e = (rate − reference rate)·t is compared with its photon shot noise √N, N = reference rate · t,
at the lowest EV the experiment tests (t = auto-exposure · 2^EV_min). Reported per frame:

    median_ratio   median |e|/√N ÷ 0.6745 (the σ ratio for Gaussian errors): ≤ TARGET_RATIO (⅓);
    p90_ratio      90th percentile |e|/√N ÷ 1.645: ≤ TAIL_RATIO (⅔);
    edge_ratio     median |e|/√N ÷ 0.6745 over object-edge pixels (a pixel whose instance id
                   differs from a 4-neighbour's, where a render is noisiest and a detector looks):
                   ≤ TAIL_RATIO;
    power_ratio    √(Σe² / ΣN): render noise power over shot noise power, all pixels (fireflies
                   weigh in here; reported, not a criterion);
    power_ratio_dim  the same over the pixels whose reference lies at or below its DIM_PERCENTILE-th
                   percentile: the dim surfaces where fireflies show, without the lamp faces,
                   sunlit exits and sky whose edge pixels otherwise carry it (city_tunnel frame 0 at
                   64 spp: the top 1 % of pixels, the exit's bright border, held 95 % of the power);
    firefly_pixels how many of those dim pixels have |e| > FIREFLY_SHOT_MULTIPLE √N (for Gaussian
                   render noise at the criterion's ⅓ a 15σ event: none expected; at a bright edge
                   a pixel-area sampling error, not a firefly, so the bright tenth is left out);
    power_ratio_clipped  the same with both images clipped at the sensor's full well, as it records
                   them (given full_well_e): a lamp face or a sun glint that saturates either way
                   carries no render noise into the data, however large its error before clipping;
    edge_bias      Σe / ΣN over the edge pixels: the render's mean error there relative to the
                   signal (a blurring denoiser or a biased sampler shows here);
    median_render_rel, median_shot_rel: the two noises as fractions of the signal (÷ 0.6745 for
                   the render error).
The reference's own noise is left in e, so every figure is an upper bound.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Generator

import numpy as np

from workbench.errors import InvalidValueError, ParameterError
from workbench.jobs import Progress
from workbench.files import json_text

TARGET_RATIO = 1.0 / 3.0
TAIL_RATIO = 2.0 / 3.0
REFERENCE_SEED_TAG = 0x52454631       # 'REF1': the reference render's own noise stream
RESULT_FILE = "render-noise.json"
DIM_PERCENTILE = 90                   # power_ratio_dim reads the pixels at or below this percentile of N
FIREFLY_SHOT_MULTIPLE = 5.0           # firefly_pixels: |e| beyond this many shot-noise σ


def edge_pixels(instance_id: np.ndarray) -> np.ndarray:
    """H×W bool: pixels whose instance id differs from one of their 4-neighbours'."""
    ids = np.asarray(instance_id)
    edge = np.zeros(ids.shape, bool)
    dy, dx = ids[1:] != ids[:-1], ids[:, 1:] != ids[:, :-1]
    edge[1:] |= dy
    edge[:-1] |= dy
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    return edge


def noise_ratios(rate: np.ndarray, reference_rate: np.ndarray, exposure_s: float,
                 edges: np.ndarray | None = None, full_well_e: float | None = None) -> dict:
    """The figures of the module docstring for one frame (rates in e⁻/s per pixel, H×W; edges
    the H×W object-edge mask, for edge_ratio and edge_bias; full_well_e, for power_ratio_clipped)."""
    n = np.asarray(reference_rate, np.float64) * exposure_s
    e = (np.asarray(rate, np.float64) - np.asarray(reference_rate, np.float64)) * exposure_s
    lit = n > 0
    if not lit.any():
        raise InvalidValueError("render noise: the reference collects no electrons at this exposure")
    edge = {}
    if edges is not None and (lit & edges).any():
        ne, ee = n[lit & edges], e[lit & edges]
        edge = {"edge_ratio": float(np.median(np.abs(ee) / np.sqrt(ne)) / 0.6745),
                "edge_bias": float(np.sum(ee) / np.sum(ne)), "edge_pixels": int(ne.size)}
    clipped = {}
    if full_well_e is not None:
        if not full_well_e > 0:
            raise InvalidValueError(f"render noise: full_well_e must be > 0 e⁻ (the sensor's full well), "
                                    f"got {full_well_e}")
        ec = np.minimum(n + e, full_well_e) - np.minimum(n, full_well_e)
        clipped = {"power_ratio_clipped": float(np.sqrt(np.sum(ec[lit] ** 2) / np.sum(n[lit])))}
    n, e = n[lit], e[lit]
    r = np.abs(e) / np.sqrt(n)
    dim = n <= np.percentile(n, DIM_PERCENTILE)       # never empty: a flat frame is all dim
    return {"median_ratio": float(np.median(r) / 0.6745), "p90_ratio": float(np.percentile(r, 90) / 1.645), **edge, **clipped,
            "power_ratio": float(np.sqrt(np.sum(e * e) / np.sum(n))), "power_ratio_dim": float(np.sqrt(np.sum(e[dim] ** 2) / np.sum(n[dim]))),
            "firefly_pixels": int(np.sum(r[dim] > FIREFLY_SHOT_MULTIPLE)),
            "median_render_rel": float(np.median(np.abs(e) / n) / 0.6745),
            "median_shot_rel": float(np.median(1.0 / np.sqrt(n))), "mean_electrons": float(n.mean()),
            "pixels": int(lit.sum())}


def measure_render_noise(folder: str | Path, frames: int = 3, reference_spp: int = 4096,
                         chunk_spp: int = 256) -> Generator[Progress, None, dict]:
    """Measure the first `frames` frames of a data set (module docstring); a long job that yields
    Progress and returns the report, also written to FOLDER/render-noise.json (atomically)."""
    from workbench.detect.data import DetectionDataset, experiment_sensor, load_signal_rates
    from workbench.files import atomic_write_text
    from workbench.render.city_frame import FrameSeeds, city_optical_image, city_scene_inputs, city_scene_job
    from workbench.sensor import auto_exposure, irradiance_to_signal_rate

    for field, value in (("--frames", frames), ("--reference-spp", reference_spp), ("chunk_spp", chunk_spp)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ParameterError(field, value, "a whole number ≥ 1")
    dataset = DetectionDataset(folder)
    if frames > len(dataset.frames):
        raise ParameterError("--frames", frames, f"at most the data set's {len(dataset.frames)} frames")
    project = dataset.project
    sensor = experiment_sensor(project)
    ev_min = float(min(project.experiment.ev_biases))
    render = project.render
    inputs = city_scene_inputs(project.updated(render=render.updated(
        spp=reference_spp, target_rel_error=None, shot_noise_ratio=None, sampler="multijitter",
        chunk_spp=chunk_spp, preview_spp=chunk_spp)))
    records = dataset.frames[:frames]
    rows = []
    for k, rec in enumerate(records):
        t0 = time.perf_counter()
        seeds = FrameSeeds(**{k: int(rec.seeds[k]) for k in ("index", "arrangement", "pose", "render")},
                           city=int(rec.seeds.get("city", rec.seeds["index"])))
        seeds = replace(seeds, render=int(np.random.SeedSequence([seeds.render, REFERENCE_SEED_TAG])
                                          .generate_state(1)[0]))
        job = city_scene_job(inputs, seeds)
        while True:
            try:
                step = next(job)
            except StopIteration as stop:
                ref_render = stop.value
                break
            yield Progress(k + step.fraction, len(records),
                           f"frame {rec.index}: reference at {reference_spp} spp ({step.message})")
        ref_rate = irradiance_to_signal_rate(city_optical_image(ref_render, project.optics,
                                                                project.scene.adjust_illuminance_lux), sensor)
        rate = load_signal_rates(rec, sensor, dataset.fingerprint)[0]
        exposure_s = min(float(auto_exposure(ref_rate, sensor)) * 2.0 ** ev_min, sensor.max_exposure_s)
        edges = edge_pixels(ref_render.labels.instance_id)
        rows.append({"frame": rec.index, "exposure_s": exposure_s,
                     **noise_ratios(rate, ref_rate, exposure_s, edges, sensor.full_well_e),
                     "reference_seconds": time.perf_counter() - t0})
        yield Progress(k + 1, len(records), f"frame {rec.index}: median σ ratio {rows[-1]['median_ratio']:.3f}")
    worst = {k: max((r[k] for r in rows if k in r), default=None) for k in ("median_ratio", "p90_ratio", "edge_ratio")}
    report = {"dataset": str(dataset.folder), "fingerprint": dataset.fingerprint,
              "render": {"sampler": render.sampler, "spp": render.spp, "chunk_spp": render.chunk_spp,
                         "preview_spp": render.preview_spp},
              "reference": {"spp": reference_spp, "sampler": "multijitter", "chunk_spp": chunk_spp},
              "lowest_ev": ev_min, "target_ratio": TARGET_RATIO, "tail_ratio": TAIL_RATIO, "frames": rows,
              "worst_median_ratio": worst["median_ratio"], "worst_p90_ratio": worst["p90_ratio"],
              "worst_edge_ratio": worst["edge_ratio"],
              "passes": bool(worst["median_ratio"] <= TARGET_RATIO and worst["p90_ratio"] <= TAIL_RATIO
                             and worst["edge_ratio"] is not None and worst["edge_ratio"] <= TAIL_RATIO)}
    if worst["edge_ratio"] is None:
        report["worst_edge_ratio_reason"] = "undefined (no object edges in the measured frames)"
    atomic_write_text(Path(folder) / RESULT_FILE, json_text(report) + "\n")
    return report
