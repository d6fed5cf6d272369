"""A synthetic frame renderer for `run_dataset` (no Mitsuba): flat-coloured boxes on a road and a
sky, as sensor-channel irradiance with exact labels, for tests and checks of the detection code.

Each object class has its own shape and colour (car: wide and red, pedestrian: tall and blue,
bus: large and yellow); positions come from the frame's arrangement seed, so frames differ and a
set is reproducible. The last object of every frame is 3 px tall (below the label rule's minimum
height: an 'ignored' box).
"""
from __future__ import annotations

import numpy as np

from workbench.render.city_frame import FrameData
from workbench.render.labels import Labels, ObjectLabel

# class name → (height, width as fractions of the frame rows, channel radiance factors R, G, B)
SHAPES = {"car": (0.25, 0.45, (1.0, 0.15, 0.1)), "pedestrian": (0.4, 0.12, (0.1, 0.2, 1.0)),
          "bus": (0.45, 0.7, (1.0, 0.9, 0.1))}
CLASS_IDS = {"car": 1, "pedestrian": 2, "bus": 3}
BACKGROUND_E = 3.0e16             # photons/s/m²/nm of the road (the sky is twice as bright)
FOCAL_LENGTH_M, F_NUMBER = 2.3761e-3, 4.0


def synthetic_frame(project, seeds) -> FrameData:
    """One frame of project.sensor's size: 2–4 boxes plus one tiny box, sensor-channel film; the
    boxes are drawn from the frame's arrangement and pose seeds (each pose of a city is another view)."""
    from workbench.sensor.cfa import cfa_layout, channel_qe

    rows, cols = project.sensor.rows, project.sensor.cols
    _, names = cfa_layout(project.sensor.cfa_pattern)
    rng = np.random.default_rng([seeds.arrangement, seeds.pose])
    wl = np.arange(400.0, 701.0, 10.0)
    qe = np.asarray(channel_qe(project.sensor, wl))
    integrals = qe.sum(axis=0) * 10.0
    centroids = (qe * wl[:, None]).sum(axis=0) / qe.sum(axis=0)
    irr = np.full((rows, cols, len(names)), BACKGROUND_E, np.float32)
    irr[: rows // 2] *= 2.0
    instance = np.zeros((rows, cols), np.int32)
    class_map = np.zeros((rows, cols), np.int32)
    objects = []
    kinds = list(rng.choice(list(SHAPES), size=int(rng.integers(2, 5))))
    for k, cname in enumerate(kinds + ["pedestrian"]):
        fh, fw, rgb = SHAPES[cname]
        h = 3 if k == len(kinds) else max(4, int(fh * rows))
        w = max(2, int(fw * rows)) if k < len(kinds) else 2
        y0 = int(rng.integers(0, rows - h + 1))
        x0 = int(rng.integers(0, cols - w + 1))
        colour = {"R": rgb[0], "G": rgb[1], "B": rgb[2]}
        irr[y0:y0 + h, x0:x0 + w] = [BACKGROUND_E * 2.5 * colour.get(n, 0.5) for n in names]
        instance[y0:y0 + h, x0:x0 + w] = k + 1
        class_map[y0:y0 + h, x0:x0 + w] = CLASS_IDS[cname]
    for k, cname in enumerate(kinds + ["pedestrian"]):
        mask = instance == k + 1
        if not mask.any():
            continue
        ys, xs = np.nonzero(mask)
        box = (int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1))
        objects.append(ObjectLabel(k + 1, CLASS_IDS[cname], cname, box, box, int(mask.sum()), int(mask.sum()),
                                   0.0, False, 0.0, 10.0))
    depth = np.full((rows, cols), 10.0, np.float32)
    labels = Labels(depth, depth.copy(), class_map, instance, objects, {v: k for k, v in CLASS_IDS.items()})
    film = {"representation": "sensor", "channel_names": list(names),
            "channel_integrals_nm": integrals.tolist(), "channel_centroids_nm": centroids.tolist()}
    meta = {"sample_spacing_m": project.sensor.pixel_pitch_um * 1e-6, "focal_length_m": FOCAL_LENGTH_M,
            "f_number": F_NUMBER, "render": film}
    return FrameData(irr, centroids, labels, meta)


def synthetic_project(rows: int = 48, cols: int = 64):
    """The city_detection_quick sample project on a rows × cols sensor (for synthetic_frame)."""
    from workbench.project import load_project
    project = load_project("city_detection_quick")
    return project.updated(name="synthetic_detection", sensor=project.sensor.updated(rows=rows, cols=cols))


def make_synthetic_dataset(folder, frames: int = 12, rows: int = 48, cols: int = 64):
    """Render a complete synthetic data set (a `workbench dataset` folder) in this process."""
    from workbench.jobs import run_job
    from workbench.datasets.dataset import run_dataset
    project = synthetic_project(rows, cols)
    return run_job(run_dataset(project, frames, folder, workers=0, renderer=synthetic_frame))
