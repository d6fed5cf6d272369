"""One training-and-testing run as an independent job of plain data: `run_detection_job(job)`
is a module-level function of picklable input that returns a plain dict, so it runs in-process,
in a process pool or on a cluster through workbench.compute's run_jobs."""
from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from functools import lru_cache

from workbench.detect.engine import TrainConfig

BOOTSTRAP_RESAMPLES = 1000


@dataclass(frozen=True)
class DetectionJob:
    """Train `config` on the data set, then test on its test frames at each of test_evs (the
    training representation), with test-set bootstrap resamples of every mAP. checkpoint: the
    run's checkpoint file (a finished one is tested, not retrained)."""

    key: str
    dataset_dir: str
    config: TrainConfig
    test_evs: tuple[float, ...]
    checkpoint: str
    with_curves: bool = False
    bootstrap: int = BOOTSTRAP_RESAMPLES

    def __repr__(self) -> str:
        return f"DetectionJob({self.key})"


@lru_cache(maxsize=1)
def loaded_code_version() -> str:
    """The code version when this process first asked (its first run's start): the code it runs,
    even when the source tree moves on while it trains."""
    from workbench.datasets.dataset import code_version
    return code_version()


def run_detection_job(job: DetectionJob, cancel=None) -> dict:
    """Train (or resume) and test one run; return a plain dict: key, config, the split it was
    trained and tested on (DetectionDataset.split_digest), train figures (loss
    and train-mAP curves, train mAP on every training frame at the curve EV), one entry per test
    EV (mAP, AP per class, COCO AP@0.5, bootstrap mAPs, inference ms per image) and where it ran
    (machine: CPU model, bf16 in hardware, threads, wall and CPU seconds of the whole run, code
    version; a run resumed from a checkpoint counts only its last process there, and lists every
    process's machine, epochs and training seconds in train.segments)."""
    import torch

    from workbench.compute import apply_thread_budget
    from workbench.detect.data import DetectionDataset, DetectionView
    from workbench.detect.devices import cpu_has_native_bf16, cpu_model, pick_device
    from workbench.detect.engine import train_detector
    from workbench.detect.inference import evaluate_detector

    if job.config.threads:                 # the sensor's pixel threads and BLAS too, not only torch's
        apply_thread_budget(job.config.threads)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    version = loaded_code_version()
    dataset = DetectionDataset(job.dataset_dir)
    model, tr = train_detector(dataset, job.config, job.checkpoint, cancel)
    device = pick_device(job.config.device)
    cfg = job.config

    def test(positions, ev: float, **kw) -> dict:
        view = DetectionView(dataset, positions, cfg.representation, (ev,), cache_mb=cfg.cache_mb)
        t0 = time.perf_counter()
        res = evaluate_detector(model, view, dataset.class_names, device=device, batch_size=cfg.eval_batch_size,
                                workers=cfg.loader_workers, precision=cfg.precision, **kw)
        res.update({"ev": float(ev), "seconds": time.perf_counter() - t0})
        return res

    train = asdict(tr)
    train_test = test(dataset.indices("train"), cfg.curve_ev)
    train.update(train_map=train_test["map"], train_map_ev=cfg.curve_ev)
    tests = [test(dataset.indices("test"), ev, with_curves=job.with_curves, bootstrap=job.bootstrap)
             for ev in job.test_evs]
    machine = {"cpu": cpu_model(), "bf16_native": cpu_has_native_bf16(), "threads": torch.get_num_threads(),
               "wall_s": time.perf_counter() - wall0, "cpu_s": time.process_time() - cpu0,
               "code_version": version}
    return {"key": job.key, "config": json.loads(cfg.to_json()), "split_digest": dataset.split_digest,
            "train": train, "tests": tests,
            "classes": list(dataset.class_names), "device": device, "machine": machine}
