"""Progressive spectral rendering: a generator that yields progress, checks a cancel token between
chunks of samples, and returns a Scene in photons/s/sr/m²/nm (plus a depth map in JIT variants).

Chunks: a `preview_spp` chunk first (fast preview), then `chunk_spp` chunks; chunk i uses the
Mitsuba seed drawn from numpy's SeedSequence([seed, i]), so the same seed gives a bit-identical
image and different chunks are independent. The LLVM backend ignores integrator.cancel() (one
megakernel), so chunks are the cancellation points (research/mitsuba.md §5).
"""
from __future__ import annotations

import time
from typing import Generator

import numpy as np

from workbench.errors import InvalidValueError
from workbench.jobs import JobCancelled, Progress
from workbench.render.film import FilmSRFs, box_bands, raised_cosine_basis, sensor_channels, sensor_wavelength_range
from workbench.render.fog import FOG_BOX_ID
from workbench.render.labels import BACKGROUND_DEPTH_M
from workbench.render.params import RenderParams
from workbench.render.sampling import noise_constant, spp_for_error
from workbench.render.scene_builder import build_scene
from workbench.render.variants import select_variant
from workbench.scene.city.types import CameraPose, City
from workbench.scene.types import Scene

DEFAULT_RANGE_NM = (400.0, 700.0)


def film_for(params: RenderParams, sensor_qe: tuple[np.ndarray, np.ndarray] | None = None) -> FilmSRFs:
    """The film SRFs for the chosen representation; the range follows the sensor when not given."""
    if params.representation == "sensor":
        if sensor_qe is None:
            raise InvalidValueError("representation 'sensor' needs sensor_qe=(wavelengths_nm, K×Nλ QE)")
        return sensor_channels(*sensor_qe)
    if params.wavelength_min_nm is not None:
        lo, hi = params.wavelength_min_nm, params.wavelength_max_nm
    elif sensor_qe is not None:
        lo, hi = sensor_wavelength_range(*sensor_qe)
    else:
        lo, hi = DEFAULT_RANGE_NM
    if params.representation == "bands":
        return box_bands(lo, hi, params.band_count)
    return raised_cosine_basis(lo, hi, params.basis_count, params.output_step_nm)


def chunk_seed(seed: int, index: int) -> int:
    """Mitsuba seed (uint32) of chunk `index` of a render with `seed`."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def _render_chunk(mi_scene, spp: int, seed: int, index: int, sensor=0) -> np.ndarray:
    import mitsuba as mi

    # always pass spp: mi.render(spp=…) changes the sampler's count for later calls (gotcha 2)
    return np.array(mi.render(mi_scene, sensor=sensor, spp=int(spp), seed=chunk_seed(seed, index)),
                    dtype=np.float64)


def upsample_nearest(image: np.ndarray, factor: int) -> np.ndarray:
    """H×W×… → (factor·H)×(factor·W)×…, each pixel repeated over factor × factor pixels."""
    if factor == 1:
        return image
    h, w = image.shape[:2]
    out = np.empty((h, factor, w, factor) + image.shape[2:], dtype=image.dtype)
    out[...] = image[:, None, :, None]
    return out.reshape((h * factor, w * factor) + image.shape[2:])


def depth_map_m(mi_scene) -> np.ndarray | None:
    """Distance (m) from the camera centre to the first hit along each pixel-centre ray of the
    scene's sensor; sky (and the fog box, fog.py) = BACKGROUND_DEPTH_M.

    JIT variants only (one vectorised ray cast); None in the scalar variant."""
    import drjit as dr
    import mitsuba as mi

    if not mi.variant().startswith(("llvm", "cuda")):
        return None
    sensor = mi_scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().crop_size())
    idx = dr.arange(mi.UInt32, w * h)
    pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = mi_scene.ray_intersect(ray)
    hit = si.is_valid()
    for shape in mi_scene.shapes():          # the fog box encloses the city: hitting it = sky
        if shape.id() == FOG_BOX_ID:
            box = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
            hit &= dr.reinterpret_array(mi.UInt32, si.shape) != box
    # the perspective camera starts rays at the near-clip plane: measure from the camera centre
    centre = sensor.world_transform().translation()
    t = dr.select(hit, dr.norm(si.p - centre), BACKGROUND_DEPTH_M)
    dr.eval(t)
    return np.array(t, dtype=np.float32).reshape(h, w)


def render_loaded(mi_scene, film: FilmSRFs, params: RenderParams, *, fov_deg: float,
                  cancel=None, name: str = "render", depth_m: np.ndarray | None = None,
                  coarse_sensor=None, coarse_factor: int = 1) -> Generator[Progress, None, Scene]:
    """Render an already loaded scene (build_scene) progressively; return its spectral Scene.

    Yields Progress (samples per pixel done of planned; preview: the radiance so far, H×W×Nλ
    float32 photons/s/sr/m²/nm) after every chunk; between chunks, a set `cancel` (a CancelToken,
    or anything with is_set()) stops the render: the samples so far are returned with
    meta['cancelled'] = True, or JobCancelled is raised when no chunk had finished.
    depth_m: the scene's depth map where the caller has cast it already (a label pass), so it is
    not cast again; else depth_map_m.
    coarse_sensor: a quick look — the samples are drawn through this sensor
    (scene_builder.coarse_pinhole, coarse_factor times coarser per side) and each of its pixels
    is repeated over the coarse_factor × coarse_factor pixels it covers."""
    import mitsuba as mi

    if params.shot_noise_ratio is not None:
        raise InvalidValueError("render.shot_noise_ratio needs the project's sensor to turn into a target error; "
                         "render a city project (render_city_frame) or give spp / target_rel_error")
    t0 = time.perf_counter()
    acc, done, index, c_meas, cancelled = None, 0, 0, None, False

    def add(img, spp):
        nonlocal acc, done, index
        acc = img * spp if acc is None else acc + img * spp
        done += spp
        index += 1

    sensor = 0 if coarse_sensor is None else coarse_sensor
    factor = 1 if coarse_sensor is None else int(coarse_factor)

    def preview():
        return upsample_nearest(film.channels_to_radiance(acc / done).astype(np.float32), factor)

    last = None                      # the preview of the last chunk: the final radiance, made once

    if params.spp is None:
        pilots = []
        for _ in range(2):
            if (cancel is not None and cancel.is_set()):
                cancelled = True
                break
            pilots.append(_render_chunk(mi_scene, params.pilot_spp, params.seed, index, sensor))
            add(pilots[-1], params.pilot_spp)
        if len(pilots) == 2:
            c_meas = noise_constant(*pilots, params.pilot_spp, params.error_metric)
            total = max(spp_for_error(c_meas, params.target_rel_error, params.max_spp), done)
        else:
            total = done
        if acc is not None:
            c_txt = "n/a" if c_meas is None else f"{c_meas:.3g}"
            yield Progress(done, total, f"pilot: c = {c_txt}, {total} spp for {params.target_rel_error:.3g} "
                                        f"{params.error_metric} error", preview())
    else:
        total = params.spp
    while not cancelled and done < total:
        if (cancel is not None and cancel.is_set()):
            cancelled = True
            break
        k = min(params.preview_spp if done == 0 else params.chunk_spp, total - done)
        add(_render_chunk(mi_scene, k, params.seed, index, sensor), k)
        last = preview()
        yield Progress(done, total, f"{done}/{total} spp", last)
    cancelled = cancelled or done < total
    if acc is None:
        raise JobCancelled(f"{name}: cancelled before the first chunk finished")
    if not np.isfinite(np.sum(acc, dtype=np.float64)):          # NaN/Inf propagate into the sum
        raise InvalidValueError(f"{name}: the renderer returned NaN/Inf radiance (variant, scene or spectra)")
    radiance = last if last is not None else preview()
    depth = depth_m if depth_m is not None else depth_map_m(mi_scene)
    hits = depth[depth < BACKGROUND_DEPTH_M] if depth is not None else np.zeros(0)
    meta = {"representation": film.kind, "spp": done, "spp_planned": total, "cancelled": cancelled,
            "noise_constant": c_meas, "variant": mi.variant(), "seed": params.seed,
            "render_s": time.perf_counter() - t0, "channel_names": list(film.names),
            "channel_integrals_nm": film.integrals_nm.tolist(),
            "channel_centroids_nm": film.centroids_nm.tolist(), "coarse_factor": factor}
    return Scene(radiance.astype(np.float32, copy=False), film.output_wavelengths_nm, float(fov_deg),
                 distance_m=float(np.median(hits)) if hits.size else BACKGROUND_DEPTH_M,
                 depth_m=depth, name=name, meta=meta)


def render_spectral(city: City, pose: CameraPose, params: RenderParams, *, width: int, height: int,
                    fov_deg: float, sensor_qe: tuple[np.ndarray, np.ndarray] | None = None,
                    lens_sensor: dict | None = None, cancel=None,
                    name: str = "city") -> Generator[Progress, None, Scene]:
    """Render the city from `pose` into a spectral Scene (photons/s/sr/m²/nm), progressively.

    sensor_qe: (wavelengths_nm, K×Nλ QE) of the camera; it sets the wavelength range (unless
    params give one) and is the film for representation 'sensor'. lens_sensor: an optional
    Mitsuba sensor dict replacing the pinhole (fov_deg must then describe it). Drive with
    `scene = yield from render_spectral(...)` or `workbench.jobs.run_job(render_spectral(...))`."""
    select_variant(params.variant, strict=params.variant is not None)
    film = film_for(params, sensor_qe)
    mi_scene, _ = build_scene(city, pose, fov_deg, width, height, film, params.daylight,
                              lens_sensor, max_depth=params.max_depth, sampler=params.sampler)
    return (yield from render_loaded(mi_scene, film, params, fov_deg=fov_deg, cancel=cancel, name=name))


