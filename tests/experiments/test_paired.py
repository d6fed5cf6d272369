"""Paired statistics against hand-worked numbers, and the contrasts and claims built on them."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.experiments.analysis import claims, contrasts, summarise
from workbench.experiments.paired import Interval, paired_difference, percentile_interval, t_interval


def test_paired_difference_by_hand():
    a, b = [0.50, 0.55, 0.60], [0.45, 0.52, 0.50]            # d = 0.05, 0.03, 0.10
    u = np.linspace(-0.1, 0.1, 1000)
    a_boot = np.array(a)[:, None] + u[None, :]
    b_boot = np.repeat(np.array(b)[:, None], 1000, axis=1)
    iv = paired_difference(a, b, a_boot, b_boot)
    sd = np.sqrt((0.01 ** 2 + 0.03 ** 2 + 0.04 ** 2) / 2)      # 0.036056
    half = 4.302653 * sd / np.sqrt(3)                          # t(0.975, 2) = 4.302653
    assert iv.mean == pytest.approx(0.06) and iv.sd == pytest.approx(sd) and iv.n == 3
    assert (iv.t_low, iv.t_high) == pytest.approx((0.06 - half, 0.06 + half), rel=1e-6)
    assert (iv.boot_low, iv.boot_high) == pytest.approx((0.06 - 0.095, 0.06 + 0.095))   # 2.5 / 97.5 % of u
    assert iv.side() == 0                                      # both intervals hold 0
    assert Interval(0.1, 3, 0.01, 0.05, 0.15, 0.06, 0.14).side() == 1
    assert Interval(-0.1, 3, 0.01, -0.15, -0.05, -0.14, -0.01).side() == -1
    assert Interval(0.1, 3, 0.01, 0.05, 0.15, -0.01, 0.2).side() == 0          # one interval holds 0
    assert Interval(-0.02, 3, 0.01, -0.04, 0.0, -0.03, -0.01).side_of(-0.05) == 1


def test_intervals_need_enough_values():
    assert t_interval([0.4])[1:] == (None, None, None)
    assert percentile_interval(np.arange(10.0)) == (None, None)
    with pytest.raises(ValueError):
        paired_difference([0.1, 0.2], [0.1, 0.2], np.zeros((3, 50)), np.zeros((3, 50)))


def _run(net, cond, seed, maps, boot_shift=0.0, train_ev=None, rep="srgb"):
    role = {"net": net, "representation": rep, "condition": cond, "seed": seed}
    if train_ev is not None:
        role["train_ev"] = train_ev
    key = f"{net}-{rep}-{cond}-{train_ev}-{seed}"
    run = {"key": key, "role": role, "tests": [{"ev": ev, "map": m} for ev, m in maps.items()]}
    rng = np.random.default_rng(abs(hash(key)) % 2 ** 32)
    boots = {ev: m + boot_shift + 0.01 * rng.standard_normal(200) for ev, m in maps.items()}
    return run, boots


def _exposure_runs(mix_gain: float, asym: float, drop_mobile: float, drop_resnet: float):
    evs = (-2.0, -1.0, 0.0, 1.0, 2.0)
    runs, boots = [], {}
    for seed in range(4):
        jitter = 0.002 * seed
        for net, drop in (("mobile", drop_mobile), ("resnet18", drop_resnet)):
            ev0 = {ev: 0.6 * (1 - drop * abs(ev) / 2) + (asym * abs(ev) / 2 if ev < 0 else 0.0) + jitter for ev in evs}
            mix = {ev: ev0[ev] + (mix_gain if ev != 0 else -0.01) for ev in evs}
            for cond, maps in (("ev0_trained", ev0), ("ev_mix", mix)):
                run, b = _run(net, cond, seed, maps)
                runs.append(run)
                boots[run["key"]] = b
    return runs, boots, evs


def test_contrasts_are_paired_differences_and_claims_follow_them():
    runs, boots, evs = _exposure_runs(mix_gain=0.1, asym=0.05, drop_mobile=0.6, drop_resnet=0.3)
    rows = contrasts("exposure", runs, boots, evs)
    get = {(r["contrast"], r["net"], r["test_ev"]): r for r in rows}
    assert get[("ev_mix − ev0_trained", "mobile", -2.0)]["mean"] == pytest.approx(0.1)
    assert get[("ev_mix − ev0_trained", "mobile", 0.0)]["mean"] == pytest.approx(-0.01)
    assert get[("ev_mix − ev0_trained", "mobile", "all")]["mean"] == pytest.approx(0.1)
    assert get[("relative drop", "mobile", 2.0)]["mean"] == pytest.approx(0.6, abs=0.01)
    # mean relative drop over EV ±1, ±2 (the under-exposed side lifted by asym): mobile 0.419, resnet18 0.194
    assert get[("relative drop resnet18 − mobile", "both", "all")]["mean"] == pytest.approx(-0.225, abs=0.005)
    assert get[("under − over", "resnet18", 2.0)]["mean"] == pytest.approx(0.05)
    isp = [{"contrast": "raw − srgb", "net": "resnet18", "test_ev": 0.0, "mean": -0.01, "n": 4, "sd": 0.01,
            "t_low": -0.03, "t_high": 0.01, "boot_low": -0.04, "boot_high": 0.02},
           {"contrast": "(raw − srgb) mobile − resnet18", "both": 0, "net": "both", "test_ev": 0.0, "mean": -0.05,
            "n": 4, "sd": 0.01, "t_low": -0.07, "t_high": -0.03, "boot_low": -0.09, "boot_high": -0.01}]
    verdicts = {c["claim"]: c["verdict"] for c in claims(isp, rows)}
    assert verdicts == {1: "supported", 2: "supported", 3: "supported", 4: "supported"}

    flat, flat_boots, _ = _exposure_runs(mix_gain=-0.1, asym=0.0, drop_mobile=0.3, drop_resnet=0.6)
    verdicts = {c["claim"]: c["verdict"] for c in claims([], contrasts("exposure", flat, flat_boots, evs))}
    assert verdicts == {1: "not supported", 2: "not supported", 3: "not resolved", 4: "not resolved"}


def test_summary_means_with_both_intervals():
    runs, boots, evs = _exposure_runs(mix_gain=0.1, asym=0.0, drop_mobile=0.5, drop_resnet=0.5)
    rows = summarise("exposure", runs, boots)
    row = next(r for r in rows if r["net"] == "mobile" and r["condition"] == "ev0_trained" and r["test_ev"] == 0.0)
    assert row["n"] == 4 and row["mean_map"] == pytest.approx(0.603)
    assert row["ci95_low"] < row["mean_map"] < row["ci95_high"]
    assert row["boot_low"] < row["mean_map"] < row["boot_high"]
