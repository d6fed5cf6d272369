"""Paired statistics against hand-worked numbers, and the contrasts and claims built on them."""
from __future__ import annotations

import numpy as np
import pytest

from scipy import stats

from workbench.experiments.analysis import claims, contrasts, holm, summarise
from workbench.experiments.paired import (one_sided_p, p_key, paired_difference, percentile_interval, t_interval,
                                          two_level_draws)


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
    assert iv.h_low < iv.boot_low and iv.h_high > iv.boot_high     # seeds and test set vary: wider


def test_two_level_draws_reduce_to_each_level():
    u = np.linspace(-0.1, 0.1, 1000)
    test_set_only = two_level_draws(0.06 + np.repeat(u[None, :], 4, axis=0))       # every seed the same
    assert percentile_interval(test_set_only) == pytest.approx((0.06 - 0.095, 0.06 + 0.095), abs=0.003)
    d = np.array([0.05, 0.03, 0.10, 0.02, 0.06])
    seeds_only = two_level_draws(np.repeat(d[:, None], 50, axis=1))               # no test-set variation
    # widened to the t-interval: sd of the draws t(0.975, 4)/z(0.975) · sd/√n (within 3 % MC error)
    want = stats.t.ppf(0.975, 4) / stats.norm.ppf(0.975) * d.std(ddof=1) / np.sqrt(5)
    assert seeds_only.mean() == pytest.approx(d.mean(), abs=0.002) and seeds_only.std() == pytest.approx(want, rel=0.03)
    constant = two_level_draws(np.full((3, 40), 0.25))
    assert constant.size == 4000
    assert one_sided_p(constant, 0.1, 1) == pytest.approx(1 / 4001) and one_sided_p(constant, 0.1, -1) == 1.0
    assert one_sided_p(constant, 0.25, 1) == 1.0                    # on the bound counts against
    iv = paired_difference([0.3, 0.3, 0.3], [0.1, 0.1, 0.1], np.full((3, 40), 0.3), np.full((3, 40), 0.1),
                           bounds=(0.0, 0.15))
    assert iv.to_dict()[p_key(1, 0.15)] == pytest.approx(1 / 4001) and iv.to_dict()[p_key(-1, 0.0)] == 1.0


def test_holm_by_hand():
    # sorted 0.005, 0.01, 0.03, 0.04 → ×4, ×3, ×2, ×1 = 0.02, 0.03, 0.06, 0.04 → running max
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.6, 0.9]) == [1.0, 1.0]


def test_intervals_need_enough_values():
    assert t_interval([0.4])[1:] == (None, None, None)
    assert percentile_interval(np.arange(10.0)) == (None, None)
    assert two_level_draws(np.zeros((1, 50))).size == 0 and one_sided_p(np.zeros(0), 0.0, 1) is None
    iv = paired_difference([0.4], [0.3], np.zeros((1, 50)), np.zeros((1, 50)), bounds=(0.0,))
    assert iv.h_low is None and iv.to_dict()[p_key(1, 0.0)] is None
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
    isp = [_row("raw − srgb", "resnet18", -0.01, above=0.2, below=0.8, above_margin=0.001, below_margin=0.999),
           _row("(raw − srgb) mobile − resnet18", "both", -0.05, above=0.999, below=0.001)]
    verdicts = {c["claim"]: c["verdict"] for c in claims(isp, rows)}
    assert verdicts == {1: "supported", 2: "supported", 3: "supported", 4: "supported"}

    flat, flat_boots, _ = _exposure_runs(mix_gain=-0.1, asym=0.0, drop_mobile=0.3, drop_resnet=0.6)
    verdicts = {c["claim"]: c["verdict"] for c in claims([], contrasts("exposure", flat, flat_boots, evs))}
    assert verdicts == {1: "not supported", 2: "not supported", 3: "not resolved", 4: "not resolved"}


def _row(contrast, net, mean, above, below, above_margin=None, below_margin=None, ev=0.0):
    """A contrast row as analysis writes it, with the given two-level p-values at 0 and −0.05."""
    return {"contrast": contrast, "net": net, "test_ev": ev, "mean": mean, "n": 5, "sd": 0.01, "t_low": None,
            "t_high": None, "boot_low": None, "boot_high": None, "h_low": None, "h_high": None,
            p_key(1, 0.0): above, p_key(-1, 0.0): below, p_key(1, -0.05): above_margin, p_key(-1, -0.05): below_margin}


def _claim2(*p_pairs):
    """Claim 2's verdict and parts from (p above 0 over EV ≠ 0, p above −0.05 at EV 0) per net."""
    rows = []
    for net, (p_all, p_ev0) in zip(("mobile", "resnet18"), p_pairs):
        rows += [_row("ev_mix − ev0_trained", net, 0.0, p_all, 1 - p_all, ev="all"),
                 _row("ev_mix − ev0_trained", net, 0.0, 0.5, 0.5, p_ev0, 1 - p_ev0)]
    claim = next(c for c in claims([], rows) if c["claim"] == 2)
    return claim["verdict"], [p["verdict"] for p in claim["parts"]]


def test_claim_of_several_parts():
    # an intersection: every part at ALPHA = 0.025, no correction
    assert _claim2((0.02, 0.02), (0.024, 0.001)) == ("supported", ["supported"] * 4)
    # one part unresolved is not evidence against: not resolved, never not supported
    assert _claim2((0.001, 0.001), (0.001, 0.3)) == ("not resolved", ["supported"] * 3 + ["not resolved"])
    # evidence against, Holm over the 4 parts: p_against 0.005 → 0.02 rejects, 0.01 → 0.04 does not
    assert _claim2((0.001, 0.001), (0.001, 0.995))[0] == "not supported"
    assert _claim2((0.001, 0.001), (0.001, 0.99)) == ("not resolved", ["supported"] * 3 + ["not resolved"])
    older = {k: v for k, v in _row("relative drop resnet18 − mobile", "both", -0.2, 0.9, 0.1, ev="all").items()
             if not k.startswith("p_")}                                    # results written before p-values
    claim1 = claims([], [older])[0]
    assert claim1["verdict"] == "not resolved" and "p-value" in claim1["parts"][0]["why"]


def test_two_sided_part_is_holm_over_its_directions():
    def claim4(p_below):
        rows = [_row("under − over", "mobile", 0.03, 1 - p_below, p_below, ev="all")]
        part = next(c for c in claims([], rows) if c["claim"] == 4)["parts"][0]
        return part["verdict"], part["p"]
    assert claim4(0.01) == ("supported", pytest.approx(0.02))
    assert claim4(0.02) == ("not resolved", pytest.approx(0.04))     # a one-sided 0.02 is not enough
    assert claim4(0.999)[0] == "supported"                            # either direction
    assert claim4(0.5)[0] == "not resolved"                           # never not supported


def test_summary_means_with_both_intervals():
    runs, boots, evs = _exposure_runs(mix_gain=0.1, asym=0.0, drop_mobile=0.5, drop_resnet=0.5)
    rows = summarise("exposure", runs, boots)
    row = next(r for r in rows if r["net"] == "mobile" and r["condition"] == "ev0_trained" and r["test_ev"] == 0.0)
    assert row["n"] == 4 and row["mean_map"] == pytest.approx(0.603)
    assert row["ci95_low"] < row["mean_map"] < row["ci95_high"]
    assert row["boot_low"] < row["mean_map"] < row["boot_high"]
