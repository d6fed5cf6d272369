"""`workbench bench detect`: what one image costs the detection study, per representation and network.

Rows of three kinds; view and network rows at 320×240 and 640×480 (--quick: 320×240 only):
  view     sensor (exposure, noise, ADC) + ISP + network_input ms per image, from the cached pixel
           signal of the paper camera's Macbeth chart (what a data view does per frame; raw needs no ISP);
  network  forward+backward (one training step without the optimiser) and inference (eval mode,
           no grad) ms per image at batch 4, for each built-in net on sRGB (3×H×W) and packed-raw
           (4×H/2×W/2) input; on the CPU with torch.set_num_threads(1), and on CUDA too when present,
           at the precision training uses there (train.autocast_dtype(device, 'auto'): bf16 autocast
           on a bf16-capable GPU), with training images per second;
  train    what one training image of the experiments costs on one CPU thread: a 160×128 crop
           (the profiles' crop_hw) through a whole optimiser step (forward, loss, backward,
           AdamW) at the profiles' batch size in channels-last order, plus the view's sensor +
           ISP + input for that crop; fp32 and bf16 autocast (the CPU has no faster path: the
           bf16 row says whether that still holds on this CPU).
"""
from __future__ import annotations

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import median_times_ms

BATCH = 4
NUM_CLASSES = 3
NETWORKS = ("mobile", "resnet18")
TRAIN_CROP_HW = (128, 160)
TRAIN_BATCH = 16


def _view_rows(rows: int, cols: int, repeats: int) -> list[dict]:
    from workbench.detect.representations import REPRESENTATIONS, network_input
    from workbench.isp import sensor_image_to_srgb
    from workbench.pipeline import Pipeline
    from workbench.project import load_project
    from workbench.sensor import irradiance_to_signal_rate, resolve_exposure, signal_rate_to_sensor_image
    from workbench.sensor.signal import colour_wavelengths_nm

    base = load_project("paper_camera")
    pitch = base.sensor.pixel_pitch_um * base.sensor.cols / cols       # same field of view at every size
    project = base.updated(sensor=base.sensor.updated(rows=rows, cols=cols, pixel_pitch_um=pitch),
                           scene=base.scene.updated(kind="macbeth"))
    oi = Pipeline(project).optical_image()
    rate = irradiance_to_signal_rate(oi, project.sensor)
    rng = np.random.default_rng(0)
    t = resolve_exposure(rate, project.sensor)

    def capture():
        return signal_rate_to_sensor_image(rate, project.sensor, t, rng, wavelengths_nm=colour_wavelengths_nm(oi))
    image = capture()
    isp = sensor_image_to_srgb(image, project.isp)
    sensor_ms = median_times_ms(capture, repeats).wall_ms
    isp_ms = median_times_ms(lambda: sensor_image_to_srgb(image, project.isp), repeats).wall_ms
    out = []
    for rep in REPRESENTATIONS:
        input_ms = median_times_ms(lambda r=rep: network_input(image, isp, r), repeats).wall_ms
        uses_isp = rep != "raw"
        out.append({"kind": "view", "size": f"{cols}x{rows}", "what": rep, "device": "cpu",
                    "sensor_ms": sensor_ms, "isp_ms": isp_ms if uses_isp else 0.0, "input_ms": input_ms,
                    "total_ms_per_image": sensor_ms + (isp_ms if uses_isp else 0.0) + input_ms})
    return out


def _network_rows(rows: int, cols: int, repeats: int, device: str) -> list[dict]:
    import torch

    from workbench.detect.centernet import centernet_loss, collate_targets, encode_targets
    from workbench.detect.devices import autocast, autocast_dtype, prepare_input, prepare_model
    from workbench.detect.models import build_detector

    dtype = autocast_dtype(device, "auto")

    def sync():
        if device == "cuda":
            torch.cuda.synchronize()

    boxes = [[cols * 0.2, rows * 0.3, cols * 0.4, rows * 0.6], [cols * 0.6, rows * 0.5, cols * 0.7, rows * 0.9]]
    targets = collate_targets([encode_targets(boxes, [0, 1], NUM_CLASSES, (rows, cols))] * BATCH)
    targets = {k: v.to(device) for k, v in targets.items()}
    out = []
    for name in NETWORKS:
        for rep, channels, stride in (("srgb", 3, 1), ("raw", 4, 2)):
            torch.manual_seed(0)
            net = prepare_model(build_detector(name, channels, NUM_CLASSES, stride), device)
            x = prepare_input(torch.rand(BATCH, channels, rows // stride, cols // stride), device)

            def train_step():
                net.train()
                net.zero_grad(set_to_none=True)
                with autocast(device, dtype):
                    y = net(x)
                centernet_loss({k: v.float() for k, v in y.items()}, targets)[0].backward()
                sync()

            def infer():
                net.eval()
                with torch.no_grad(), autocast(device, dtype):
                    net(x)
                sync()
            train, infer_t = median_times_ms(train_step, repeats), median_times_ms(infer, repeats)
            out.append({"kind": "network", "size": f"{cols}x{rows}", "what": f"{name} {rep}", "device": device,
                        "precision": "bf16" if dtype is not None else "fp32",
                        "params_M": sum(p.numel() for p in net.parameters()) / 1e6,
                        "train_ms_per_image": train.wall_ms / BATCH, "infer_ms_per_image": infer_t.wall_ms / BATCH,
                        "train_images_per_s": 1e3 * BATCH / train.wall_ms,
                        "train_cpu_ms_per_image": train.cpu_ms / BATCH, "infer_cpu_ms_per_image": infer_t.cpu_ms / BATCH})
    return out


def _train_rows(repeats: int, view_ms: dict) -> list[dict]:
    import torch

    from workbench.detect.centernet import centernet_loss, collate_targets, encode_targets
    from workbench.detect.devices import autocast, prepare_input, prepare_model
    from workbench.detect.models import build_detector

    rows, cols = TRAIN_CROP_HW
    boxes = [[cols * 0.2, rows * 0.3, cols * 0.4, rows * 0.6], [cols * 0.6, rows * 0.5, cols * 0.7, rows * 0.9]]
    targets = collate_targets([encode_targets(boxes, [0, 1], NUM_CLASSES, (rows, cols))] * TRAIN_BATCH)
    out = []
    for name in NETWORKS:
        for rep, channels, stride in (("srgb", 3, 1), ("raw", 4, 2)):
            for dtype in (None, torch.bfloat16):
                torch.manual_seed(0)
                net = prepare_model(build_detector(name, channels, NUM_CLASSES, stride), "cpu")
                opt = torch.optim.AdamW(net.parameters(), lr=1e-3)
                x = prepare_input(torch.rand(TRAIN_BATCH, channels, rows // stride, cols // stride), "cpu")
                net.train()

                def step():
                    with autocast("cpu", dtype):
                        y = net(x)
                    loss = centernet_loss({k: v.float() for k, v in y.items()}, targets)[0]
                    opt.zero_grad(set_to_none=True)
                    loss.backward()
                    opt.step()
                t = median_times_ms(step, repeats)
                step_ms = t.wall_ms / TRAIN_BATCH
                data_ms = view_ms[rep]
                out.append({"kind": "train", "size": f"{cols}x{rows}", "what": f"{name} {rep}", "device": "cpu",
                            "precision": "bf16" if dtype is not None else "fp32",
                            "step_ms_per_image": step_ms, "view_ms_per_image": data_ms,
                            "train_ms_per_image": step_ms + data_ms, "train_images_per_s": 1e3 / (step_ms + data_ms),
                            "step_cpu_ms_per_image": t.cpu_ms / TRAIN_BATCH})
    return out


@register_bench("detect", help="sensor + ISP + input ms per image per representation; detector train/infer ms")
def bench_detect(args) -> BenchResult:
    import torch

    quick = bool(getattr(args, "quick", False))
    sizes = [(240, 320)] if quick else [(240, 320), (480, 640)]
    repeats = 2 if quick else 5
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        rows = []
        for r, c in [TRAIN_CROP_HW] + sizes:
            rows += _view_rows(r, c, 3 * repeats)
        crop_view = {row["what"]: row["total_ms_per_image"] for row in rows[:3]}
        rows += _train_rows(max(repeats, 3), crop_view)
        devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
        for device in devices:
            for r, c in sizes:
                rows += _network_rows(r, c, repeats, device)
    finally:
        torch.set_num_threads(threads)
    notes = ["torch.set_num_threads(1) for every CPU row (the study's training setting); batch "
             f"{BATCH}, per-image = batch time / {BATCH}; medians of {repeats} runs after a warm-up "
             f"(views: {3 * repeats})",
             "view: paper camera, Macbeth chart; sensor = signal_rate_to_sensor_image (noise, ADC) from the cached pixel signal; "
             "raw skips the ISP; input = network_input (scaling, packing, layout)",
             "network train = forward + loss + backward (no optimiser step); raw input is packed 4×H/2×W/2",
             f"train = one training image of the experiments: a {TRAIN_CROP_HW[1]}×{TRAIN_CROP_HW[0]} crop, a whole "
             f"AdamW step at batch {TRAIN_BATCH} in channels-last order (step_ms) + sensor, ISP and input for the crop "
             "(view_ms, the view row of that size)",
             "*_ms = wall clock; *_cpu_ms = process CPU time (the robust figure when other processes share the cores)"]
    return BenchResult("bench detect: ms per image for data views and detectors", rows, notes,
                       extra={"batch": BATCH, "torch_threads": 1, "devices": devices})
