"""What the runs of a detection experiment say: per-condition means, paired contrasts, and the
paper's four claims with a verdict each.

Inputs are the finished runs of a results document and their test-set bootstrap resamples
(`Bootstraps`: run key → test EV → resampled mAPs, the same resamples for every run).
Every interval is a paired one (workbench.experiments.paired): conditions are compared on the
same seeds and the same test captures.

Contrasts (rows of `contrasts`, each with the two-level 95 % interval h_low, h_high that verdicts
read, its one-sided p-values above and below each CLAIM_BOUNDS bound (keys paired.p_key), and the
descriptive seed t and test-set intervals):
    isp        raw − srgb and linear − srgb mAP per net (EV 0)
    exposure   per net and test EV: ev_mix − ev0_trained; per_ev − ev0_trained (at the EVs with
               a per-EV run); relative drop 1 − mAP(EV)/mAP(0) of the EV-0-trained net, and
               resnet18 − mobile of it; under − over asymmetry mAP(−k) − mAP(+k) (k > 0).
               'all' rows average a contrast over the test EVs ≠ 0.

Claims (the paper's, `claims`), each supported / not supported / not resolved:
    1 heavier net degrades less       resnet18 − mobile relative drop, averaged over EV ≠ 0, < 0
    2 EV mix flattens the curve at a  ev_mix − ev0_trained averaged over EV ≠ 0 > 0, and at EV 0
      small cost at EV 0              > −EQUIVALENCE_MARGIN (per net)
    3 raw not much worse than sRGB    resnet18 raw − srgb > −EQUIVALENCE_MARGIN, and
      for the heavier net; the light  (raw − srgb)_mobile − (raw − srgb)_resnet18 < 0
      net loses more on raw
    4 under- and over-exposure        mAP(−k) − mAP(+k) of the EV-0-trained net, averaged over
      behave differently              k = 1…4, ≠ 0 (per net)
Tests, per claim (the family: its parts), at one-sided level ALPHA = 0.025 (that of a two-sided
95 % interval), with p the part's two-level p-value of lying on its side of its bound:
    supported      every part has p ≤ ALPHA. Each claim is the intersection of its parts, so this
                   intersection-union test holds the false-"supported" rate of the claim at ALPHA
                   without correction (Holm here would only cost power).
    not supported  the evidence is against it: some part's p of lying on the wrong side of its
                   bound (p_against) is ≤ ALPHA after Holm over the claim's parts, which are
                   alternative ways for the claim to fail. An unresolved part is not evidence.
    not resolved   otherwise.
A part of claim 4 is itself two alternatives (above or below 0): Holm over them, p = min(1,
2·min(p_above, p_below)); nothing can show a difference of exactly 0, so it is never not supported.
"""
from __future__ import annotations

import math

import numpy as np

from workbench.experiments.paired import Interval, p_key, paired_difference, percentile_interval, t_interval

EQUIVALENCE_MARGIN = 0.05         # mAP: "not much worse" means within this of the other condition
CLAIM_BOUNDS = (0.0, -EQUIVALENCE_MARGIN)
ALPHA = 0.025                     # one-sided level of each claim's tests (module docstring)
REPRESENTATION_ORDER = ("raw", "linear", "srgb")
CONDITIONS = ("ev0_trained", "ev_mix", "per_ev")

Bootstraps = dict  # run key → {test EV: np.ndarray of resampled mAPs}


def _maps(run: dict) -> dict[float, float]:
    return {float(t["ev"]): (math.nan if t["map"] is None else float(t["map"])) for t in run["tests"]}


def _boot_maps(run: dict, boots: Bootstraps) -> dict[float, np.ndarray] | None:
    return boots.get(run["key"])


def _select(runs: list[dict], **role) -> dict[int, dict]:
    """Runs whose role matches, by seed."""
    return {r["role"]["seed"]: r for r in runs if all(r["role"].get(k) == v for k, v in role.items())}


def seed_values(runs: list[dict], boots: Bootstraps, fn, **role):
    """(seeds, point values, bootstrap values seeds × resamples or None) of fn(maps by test EV)
    over the runs with this role."""
    chosen = _select(runs, **role)
    seeds = sorted(chosen)
    points = np.array([fn(_maps(chosen[s])) for s in seeds], dtype=np.float64)
    boot = [_boot_maps(chosen[s], boots) for s in seeds]
    if seeds and all(b is not None for b in boot):
        try:
            boot_values = np.stack([np.asarray(fn(b), dtype=np.float64) for b in boot])
        except KeyError:
            boot_values = None
    else:
        boot_values = None
    return seeds, points, boot_values


def _paired(a, b) -> Interval | None:
    """A − B over the seeds both have (None when they share none)."""
    (sa, va, ba), (sb, vb, bb) = a, b
    common = sorted(set(sa) & set(sb))
    if not common:
        return None
    ia, ib = [sa.index(s) for s in common], [sb.index(s) for s in common]
    with_boot = ba is not None and bb is not None
    return paired_difference(va[ia], vb[ib], ba[ia] if with_boot else None, bb[ib] if with_boot else None,
                             CLAIM_BOUNDS)


def _zero(values) -> tuple:
    seeds, points, boot = values
    return seeds, np.zeros_like(points), None if boot is None else np.zeros_like(boot)


def _at(ev: float):
    return lambda m: m[ev]


def summarise(kind: str, runs: list[dict], boots: Bootstraps) -> list[dict]:
    """Mean mAP over seeds per (net, representation, condition, test EV) with the seed t-interval
    and the test-set bootstrap interval of the mean. Exposure: the per-EV condition at a test EV
    is the run trained at that EV (at EV 0: the EV-0-trained run)."""
    out = []
    nets = sorted({r["role"]["net"] for r in runs})
    for net in nets:
        for rep in REPRESENTATION_ORDER:
            for cond in CONDITIONS:
                evs = sorted({t["ev"] for r in runs for t in r["tests"] if r["role"]["net"] == net
                              and r["role"]["representation"] == rep and r["role"]["condition"] == cond})
                if cond == "per_ev":
                    evs = sorted({float(r["role"]["train_ev"]) for r in runs if r["role"]["net"] == net
                                  and r["role"]["condition"] == "per_ev"} | ({0.0} if evs else set()))
                for ev in evs:
                    role = {"net": net, "representation": rep, "condition": cond}
                    if cond == "per_ev":
                        role = ({**role, "train_ev": ev} if ev != 0.0 else {**role, "condition": "ev0_trained"})
                    seeds, points, boot = seed_values(runs, boots, _at(ev), **role)
                    points_ok = points[np.isfinite(points)]
                    if not points_ok.size:
                        continue
                    mean, sd, lo, hi = t_interval(points_ok)
                    b_lo, b_hi = (percentile_interval(np.nanmean(boot, axis=0)) if boot is not None
                                  else (None, None))
                    out.append({"net": net, "representation": rep, "condition": cond, "test_ev": float(ev),
                                "n": int(points_ok.size), "mean_map": mean, "sd": sd, "ci95_low": lo,
                                "ci95_high": hi, "boot_low": b_lo, "boot_high": b_hi})
    return out


def _row(name: str, net: str, ev, interval: Interval | None) -> dict | None:
    if interval is None or not math.isfinite(interval.mean):
        return None
    return {"contrast": name, "net": net, "test_ev": ev, **interval.to_dict()}


def contrasts(kind: str, runs: list[dict], boots: Bootstraps, ev_biases) -> list[dict]:
    """The paired contrasts of the module docstring, one row each."""
    rows: list[dict | None] = []
    nets = sorted({r["role"]["net"] for r in runs})
    if kind == "isp":
        for net in nets:
            srgb = seed_values(runs, boots, _at(0.0), net=net, representation="srgb")
            for rep in ("raw", "linear"):
                rows.append(_row(f"{rep} − srgb", net, 0.0,
                                 _paired(seed_values(runs, boots, _at(0.0), net=net, representation=rep), srgb)))
        if {"mobile", "resnet18"} <= set(nets):
            def gap(net):
                return _difference(seed_values(runs, boots, _at(0.0), net=net, representation="raw"),
                                   seed_values(runs, boots, _at(0.0), net=net, representation="srgb"))
            rows.append(_row("(raw − srgb) mobile − resnet18", "both", 0.0, _paired(gap("mobile"), gap("resnet18"))))
        return [r for r in rows if r]
    evs = sorted(float(e) for e in ev_biases)
    nonzero = [e for e in evs if e != 0.0]
    over = [e for e in nonzero if e > 0 and -e in evs]

    def mean_of(fn, evs_):
        return lambda m: sum(fn(e)(m) for e in evs_) / len(evs_)

    def drop(e):
        def relative_drop(m):
            base = np.asarray(m[0.0], dtype=np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                return 1.0 - np.asarray(m[e], dtype=np.float64) / np.where(base > 0, base, np.nan)
        return relative_drop

    def asym(k):
        return lambda m: m[-k] - m[k]

    for net in nets:
        ev0 = {"net": net, "condition": "ev0_trained"}
        mix = {"net": net, "condition": "ev_mix"}
        for e in evs:
            rows.append(_row("ev_mix − ev0_trained", net, e, _paired(seed_values(runs, boots, _at(e), **mix),
                                                                    seed_values(runs, boots, _at(e), **ev0))))
            if e != 0.0 and _select(runs, condition="per_ev", net=net, train_ev=e):
                rows.append(_row("per_ev − ev0_trained", net, e,
                                 _paired(seed_values(runs, boots, _at(e), condition="per_ev", net=net, train_ev=e),
                                         seed_values(runs, boots, _at(e), **ev0))))
        if nonzero:
            rows.append(_row("ev_mix − ev0_trained", net, "all", _paired(
                seed_values(runs, boots, mean_of(_at, nonzero), **mix),
                seed_values(runs, boots, mean_of(_at, nonzero), **ev0))))
        for e in nonzero:
            values = seed_values(runs, boots, drop(e), **ev0)
            rows.append(_row("relative drop", net, e, _paired(values, _zero(values))))
        for k in over:
            values = seed_values(runs, boots, asym(k), **ev0)
            rows.append(_row("under − over", net, k, _paired(values, _zero(values))))
        if over:
            values = seed_values(runs, boots, mean_of(asym, over), **ev0)
            rows.append(_row("under − over", net, "all", _paired(values, _zero(values))))
    if {"mobile", "resnet18"} <= set(nets) and nonzero:
        for e in nonzero + ["all"]:
            fn = drop(e) if e != "all" else mean_of(drop, nonzero)
            rows.append(_row("relative drop resnet18 − mobile", "both", e, _paired(
                seed_values(runs, boots, fn, net="resnet18", condition="ev0_trained"),
                seed_values(runs, boots, fn, net="mobile", condition="ev0_trained"))))
    return [r for r in rows if r]


def _difference(a, b):
    """Per-seed A − B as a seed_values triple (for contrasts of contrasts)."""
    (sa, va, ba), (sb, vb, bb) = a, b
    common = sorted(set(sa) & set(sb))
    ia, ib = [sa.index(s) for s in common], [sb.index(s) for s in common]
    boot = ba[ia] - bb[ib] if ba is not None and bb is not None else None
    return common, va[ia] - vb[ib], boot


VERDICTS = ("supported", "not supported", "not resolved")


def holm(p_values: list[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values (step-down, monotone, capped at 1), in the given order."""
    k = len(p_values)
    adjusted, running = [1.0] * k, 0.0
    for rank, i in enumerate(np.argsort(p_values, kind="stable")):
        running = max(running, min(1.0, (k - rank) * p_values[i]))
        adjusted[i] = running
    return adjusted


def _part(row: dict | None, direction: int, bound: float, text: str) -> dict:
    """One part of a claim: row's two-level p-values of lying beyond `bound` in `direction` (+1:
    above, −1: below), 'p', and of lying beyond it the other way, 'p_against'."""
    if row is None:
        return {"text": text, "p": None, "p_against": None, "why": "no runs for it yet"}
    part = {"text": text, "contrast": row["contrast"], "net": row["net"], "test_ev": row["test_ev"],
            "mean": row["mean"], "bound": bound, **{k: row.get(k) for k in (
                "h_low", "h_high", "t_low", "t_high", "boot_low", "boot_high")},
            "p": row.get(p_key(direction, bound)), "p_against": row.get(p_key(-direction, bound))}
    if part["p"] is None:
        part["why"] = "no two-level p-value (under 2 seeds with test-set resamples, or results older than it)"
    return part


def _claim(number: int, text: str, parts: list[dict]) -> dict:
    """The verdicts of a claim that is the intersection of its parts (module docstring)."""
    against = holm([1.0 if p["p_against"] is None else p["p_against"] for p in parts])
    for part, adjusted in zip(parts, against):
        part["p_against_holm"] = adjusted
        part["verdict"] = ("supported" if part["p"] is not None and part["p"] <= ALPHA
                           else "not supported" if adjusted <= ALPHA else "not resolved")
    verdicts = [p["verdict"] for p in parts]
    verdict = ("supported" if parts and all(v == "supported" for v in verdicts)
               else "not supported" if "not supported" in verdicts else "not resolved")
    return {"claim": number, "text": text, "verdict": verdict, "parts": parts}


def claims(isp_contrasts: list[dict], exposure_contrasts: list[dict]) -> list[dict]:
    """The paper's four claims from the two experiments' contrasts (module docstring)."""
    def find(rows, contrast, net, ev):
        return next((r for r in rows if r["contrast"] == contrast and r["net"] == net and r["test_ev"] == ev), None)

    x, i = exposure_contrasts, isp_contrasts
    nets = sorted({r["net"] for r in x if r["net"] != "both"})
    m = EQUIVALENCE_MARGIN
    out = [
        _claim(1, "the heavier net (resnet18) loses less of its mAP away from EV 0 than the light one",
               [_part(find(x, "relative drop resnet18 − mobile", "both", "all"), -1, 0.0,
                      "resnet18 − mobile relative drop, mean over EV ≠ 0, below 0")]),
        _claim(2, "training on the EV mix flattens the curve at a small cost at EV 0",
               [p for net in nets for p in (
                   _part(find(x, "ev_mix − ev0_trained", net, "all"), 1, 0.0,
                         f"{net}: EV mix − EV-0-trained, mean over EV ≠ 0, above 0"),
                   _part(find(x, "ev_mix − ev0_trained", net, 0.0), 1, -m,
                         f"{net}: EV mix − EV-0-trained at EV 0 above −{m}"))]),
        _claim(3, "raw is not much worse than sRGB for the heavier net; the light net loses more on raw",
               [_part(find(i, "raw − srgb", "resnet18", 0.0), 1, -m, f"resnet18: raw − sRGB above −{m}"),
                _part(find(i, "(raw − srgb) mobile − resnet18", "both", 0.0), -1, 0.0,
                      "(raw − sRGB) of mobile − of resnet18 below 0")]),
        _claim(4, "under- and over-exposure by the same EV cost different amounts of mAP",
               [_two_sided(find(x, "under − over", net, "all"), f"{net}: mAP(−k) − mAP(+k), mean over k, ≠ 0")
                for net in nets]),
    ]
    return out


def _two_sided(row: dict | None, text: str) -> dict:
    """A part 'differs from 0': Holm over its two directions, p = min(1, 2·min(p_above, p_below));
    no p_against (a difference of exactly 0 cannot be shown)."""
    up, down = _part(row, 1, 0.0, text), _part(row, -1, 0.0, text)
    p = None if up["p"] is None or down["p"] is None else min(holm([up["p"], down["p"]]))
    return {**up, "p": p, "p_against": None}
