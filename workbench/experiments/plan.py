"""The plan of a detection experiment: its profiles (how big it is) and the runs each kind of
experiment trains, as (role, key, training config, test EVs). A run's key names its training
configuration, the data set's fingerprint and the split of that data set it was trained and
tested on (`run_key`), so the same training is shared by every experiment that tests it and a
record of it can be checked against its config (experiments.records)."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, fields, replace

from workbench.errors import ParameterError
from workbench.experiments.analysis import REPRESENTATION_ORDER

EXPERIMENTS = ("isp", "exposure", "budget")
BUDGET_SEEDS = 2
# The standard profile's training budget B per net: the one place it is set. `experiment budget`
# tests it against 2B; while the study says 2B gains ≥ BUDGET_TOLERANCE, B doubles here (the
# budget folder keeps every earlier step as the ladder's evidence: budget_ladder_configs).
STANDARD_EPOCHS = {"mobile": 480, "resnet18": 640}
# Batch per net: `mobile` is limited by optimizer steps, not images seen (batch 8 for 240 epochs tested
# as batch 16 for 480 at ~0.6 of its time); `resnet18` is not (batch 8 for 160 epochs tested as batch
# 16 for 160, below batch 16 for 320), so it keeps batch 16 and its batch-16 runs: docs/results/schedule-study.
STANDARD_BATCH = {"mobile": 8, "resnet18": 16}


def config_digest(config: dict, fingerprint: str, split_digest: str | None = None) -> str:
    """SHA-256 (hex) of a training config (as a JSON object), a data set's fingerprint and its split
    (DetectionDataset.split_digest; None for records made before runs named their split)."""
    parts = [json.dumps(config, sort_keys=True), fingerprint] + ([split_digest] if split_digest is not None else [])
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def run_key(config: dict, fingerprint: str, split_digest: str | None = None) -> str:
    """The key of the run of `config` on the data set of `fingerprint` split as `split_digest`:
    net, representation, training EV(s), seed and the first 10 hex digits of config_digest."""
    evs = config["train_evs"]
    ev_tag = "mix" if len(evs) > 1 else f"ev{evs[0]:+g}"
    return (f"{config['net']}-{config['representation']}-{ev_tag}-s{config['seed']}-"
            f"{config_digest(config, fingerprint, split_digest)[:10]}")


@dataclass(frozen=True)
class Profile:
    """How big an experiment is. epochs: the training budget per net (every condition of a net
    gets the same); batch_size: one for every net, or one per net (dict); precision: per net, one
    of detect.devices.PRECISIONS; per_ev_biases: the EVs at which the exposure experiment trains
    per-EV nets; crop_hw: training windows;
    curve_points: train-mAP measurements per run."""

    name: str
    image_hw: tuple[int, int]
    nets: tuple[str, ...]
    seeds: int
    epochs: dict
    batch_size: int | dict
    crop_hw: tuple[int, int] | None
    lr: float
    per_ev_biases: tuple[float, ...]
    threads: int | None
    device: str
    loader_workers: int
    cache_mb: float
    curve_points: int
    note: str
    precision: dict = field(default_factory=dict)


PROFILES = {
    "quick": Profile(
        name="quick", image_hw=(240, 320), nets=("mobile",), seeds=2, epochs={"mobile": 6, "resnet18": 6},
        batch_size=16, crop_hw=(128, 160), lr=3e-3, per_ev_biases=(), threads=1, device="cpu", loader_workers=0,
        cache_mb=1024.0, curve_points=3,
        note="quick profile: a smoke test (minutes): the 'mobile' net, 2 seeds, 6 epochs; far from converged, "
             "its mAPs say nothing about the camera"),
    "standard": Profile(
        name="standard", image_hw=(240, 320), nets=("mobile", "resnet18"), seeds=5,
        epochs=dict(STANDARD_EPOCHS), batch_size=dict(STANDARD_BATCH), crop_hw=(128, 160), lr=3e-3,
        per_ev_biases=(), threads=1, device="cpu", loader_workers=0, cache_mb=2048.0,
        curve_points=6, precision={"mobile": "fp32", "resnet18": "bf16_native"},
        note="standard profile: sized to the paper's four claims on a CPU: 320×240 frames (≥ 400 train, "
             "≥ 200 test), both nets (resnet18 22× mobile's parameters) on 160×128 windows, 5 seeds, the EV-0 "
             "and EV-mix conditions (no per-EV nets: they only draw a reference curve; the paper profile has "
             "them), one thread per run; resnet18 under bf16 autocast where the CPU computes bf16 (AVX-512 "
             "BF16/AMX), float32 where it would emulate it; `experiment budget` checks the epochs"),
    "paper": Profile(
        name="paper", image_hw=(480, 640), nets=("mobile", "resnet18"), seeds=5,
        epochs={"mobile": 60, "resnet18": 60}, batch_size=32, crop_hw=None, lr=2e-3,
        per_ev_biases=(-4.0, -3.0, -2.0, -1.0, 1.0, 2.0, 3.0, 4.0), threads=None, device="auto",
        loader_workers=12, cache_mb=4096.0, curve_points=6,
        note="paper profile: 640×480 frames, both nets, whole frames, every per-EV net: meant for a GPU "
             "(CUDA with bf16 autocast when present); on a CPU it takes days"),
}


def profile_of_settings(settings: dict) -> Profile:
    """The Profile a results document's 'settings' record (TypeError/ValueError when they are not one)."""
    values = {f.name: settings[f.name] for f in fields(Profile) if f.name in settings}
    for name in ("image_hw", "nets", "per_ev_biases"):
        values[name] = tuple(values[name])
    if values.get("crop_hw") is not None:
        values["crop_hw"] = tuple(values["crop_hw"])
    return Profile(**values)


def plan_configs(kind: str, profile: Profile, seeds: int, evs: tuple[float, ...], fingerprint: str,
                 split_digest: str | None = None):
    """The runs of an experiment as (role, key, TrainConfig, test EVs), on a data set of this
    fingerprint, split as split_digest, whose project tests the EV biases `evs` (plan_runs)."""
    from workbench.detect.engine import TrainConfig

    if kind not in EXPERIMENTS:
        raise ParameterError("experiment", kind, f"one of {', '.join(EXPERIMENTS)}")
    if 0.0 not in evs:
        raise ParameterError("experiment.ev_biases", list(evs), "a list of EV biases that includes 0")
    missing = [e for e in profile.per_ev_biases if e not in evs] if kind == "exposure" else []
    if missing:
        raise ParameterError("experiment.ev_biases", list(evs), f"a list that includes the profile's per-EV "
                                                                 f"training EVs {missing}")
    jobs = []

    def add(role: dict, config: TrainConfig, test_evs: tuple) -> None:
        jobs.append((role, run_key(json.loads(config.to_json()), fingerprint, split_digest), config, test_evs))

    def add_srgb_ev0(role: dict, config: TrainConfig) -> None:
        """The sRGB EV-0 run at the profile's budget: the same key in every experiment, tested at every EV."""
        add({**role, "representation": "srgb", "condition": "ev0_trained"}, config, evs)

    bases = {}
    for net in profile.nets:
        if net not in profile.epochs:
            raise ParameterError("profile.epochs", profile.epochs, f"a budget for net '{net}'")
        batch = profile.batch_size.get(net) if isinstance(profile.batch_size, dict) else profile.batch_size
        if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
            raise ParameterError("profile.batch_size", profile.batch_size, f"a whole number ≥ 1 for net '{net}'")
        bases[net] = TrainConfig(net=net, epochs=profile.epochs[net], batch_size=batch, lr=profile.lr,
                                 crop_hw=profile.crop_hw, threads=profile.threads, device=profile.device,
                                 loader_workers=profile.loader_workers, cache_mb=profile.cache_mb,
                                 curve_points=profile.curve_points, precision=profile.precision.get(net, "auto"))
    # seed by seed, both nets in each: whatever part of the list is done when a sitting ends is
    # paired across nets and conditions
    for seed in range(min(seeds, BUDGET_SEEDS) if kind == "budget" else seeds):
        for net, base in bases.items():
            role = {"net": net, "seed": seed}
            if kind == "budget":
                add_srgb_ev0({**role, "budget_factor": 1}, replace(base, seed=seed))
                add_srgb_ev0({**role, "budget_factor": 2}, replace(base, seed=seed, epochs=2 * base.epochs))
            elif kind == "isp":
                for rep in REPRESENTATION_ORDER:
                    if rep == "srgb":
                        add_srgb_ev0(role, replace(base, seed=seed))
                    else:
                        add({**role, "representation": rep, "condition": "ev0_trained"},
                            replace(base, representation=rep, seed=seed), (0.0,))
            else:
                srgb = {**role, "representation": "srgb"}
                add_srgb_ev0(role, replace(base, seed=seed))
                add({**srgb, "condition": "ev_mix"}, replace(base, seed=seed, train_evs=evs), evs)
                for ev in profile.per_ev_biases:
                    add({**srgb, "condition": "per_ev", "train_ev": float(ev)},
                        replace(base, seed=seed, train_evs=(float(ev),)), evs)
    return jobs


def budget_ladder_configs(profile: Profile, seeds: int, evs: tuple[float, ...], fingerprint: str,
                          split_digest: str | None = None):
    """The budget study's earlier steps below the profile's budget B, as plan_configs' tuples: per
    net and seed, the sRGB EV-0 run at B/2, B/4, … (while a whole number of epochs), its role's
    budget_factor that fraction of B. Never trained: a budget folder keeps their records in its
    runs as the evidence that the budget grew (B/2 → B is the step that said B/2 was not enough)."""
    ladder, k = [], 1
    while True:
        halved = {net: profile.epochs[net] >> k for net in profile.nets
                  if net in profile.epochs and profile.epochs[net] >> k >= 1 and profile.epochs[net] % (1 << k) == 0}
        if not halved:
            return ladder
        lower = replace(profile, nets=tuple(halved), epochs=halved)
        ladder += [({**role, "budget_factor": 1 / (1 << k)}, key, config, test_evs)
                   for role, key, config, test_evs in plan_configs("budget", lower, seeds, evs, fingerprint,
                                                                   split_digest)
                   if role["budget_factor"] == 1]
        k += 1


def kept_roles(kind: str, profile: Profile, seeds: int, evs: tuple[float, ...], fingerprint: str,
               split_digest: str | None = None) -> dict:
    """{key: role} of the records a result folder keeps in its runs: its plan's and, for the budget
    study, its ladder's (budget_ladder_configs); any other record is a superseded one."""
    jobs = plan_configs(kind, profile, seeds, evs, fingerprint, split_digest)
    if kind == "budget":
        jobs += budget_ladder_configs(profile, seeds, evs, fingerprint, split_digest)
    return {key: role for role, key, _, _ in jobs}
