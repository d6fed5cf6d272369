"""Is a training budget enough? The 'budget' experiment's reading (experiments.detection).

Per net, the runs trained on sRGB at EV 0 for B epochs (budget_factor 1) and for 2B (factor 2)
on the same seeds are tested at EV 0. The gain 2B − B of test mAP@0.5 is read paired by seed
(workbench.experiments.paired); budget B is enough for the net when the mean gain over the seeds
is below the tolerance (a run that loses with more training counts as enough), else the budget
must grow. With 2 seeds the intervals are wide: the rule reads the mean, as the study asks.
"""
from __future__ import annotations

from workbench.experiments.analysis import _paired, seed_values
from workbench.experiments.paired import t_interval

FACTORS = (1, 2)


def _at0(maps):
    return maps[0.0]


def budget_analysis(runs: list[dict], boots: dict, tolerance: float) -> dict:
    """summary (mean test mAP at EV 0 per net and budget), contrasts ('2B − B' per net) and
    budget_enough ({net: epochs B, gain, seeds, enough}) of the budget runs."""
    summary, rows, enough = [], [], {}
    for net in sorted({r["role"]["net"] for r in runs}):
        values = {f: seed_values(runs, boots, _at0, net=net, budget_factor=f) for f in FACTORS}
        epochs = {f: next((r["config"]["epochs"] for r in runs if r["role"]["net"] == net
                           and r["role"].get("budget_factor") == f), None) for f in FACTORS}
        for f in FACTORS:
            seeds, points, _ = values[f]
            if not seeds:
                continue
            mean, sd, lo, hi = t_interval(points)
            summary.append({"net": net, "representation": "srgb", "condition": f"budget ×{f}", "test_ev": 0.0,
                            "epochs": epochs[f], "n": len(seeds), "mean_map": mean, "sd": sd, "ci95_low": lo,
                            "ci95_high": hi, "per_seed": dict(zip(seeds, points.tolist()))})
        interval = _paired(values[2], values[1])                 # 2B − B on the seeds both have
        if interval is None:
            continue
        rows.append({"contrast": "2B − B", "net": net, "test_ev": 0.0, **interval.to_dict()})
        seeds = sorted(set(values[2][0]) & set(values[1][0]))
        enough[net] = {"epochs": epochs[1], "gain": interval.mean, "seeds": seeds, "enough": interval.mean < tolerance,
                       "tolerance": tolerance}
    return {"summary": summary, "contrasts": rows, "per_ev_is_upper_bound": None, "budget_enough": enough}


def draw_budget(fig, doc: dict) -> None:
    """Test mAP at EV 0 for budget B and 2B per net: one point per seed, lines joining a seed's pair."""
    ax = fig.add_subplot()
    nets = sorted({s["net"] for s in doc["summary"]})
    for k, net in enumerate(nets):
        rows = {s["condition"]: s for s in doc["summary"] if s["net"] == net}
        b, b2 = rows.get("budget ×1"), rows.get("budget ×2")
        for seed in sorted(set((b or {}).get("per_seed", {})) | set((b2 or {}).get("per_seed", {}))):
            ys = [r["per_seed"].get(seed) if r else None for r in (b, b2)]
            xs = [k - 0.15, k + 0.15]
            ax.plot([x for x, y in zip(xs, ys) if y is not None], [y for y in ys if y is not None], "o-",
                    color="tab:blue" if net == "mobile" else "tab:red", alpha=0.8)
        verdict = doc.get("budget_enough", {}).get(net)
        if verdict:
            ax.text(k, 0.02, f"B = {verdict['epochs']} epochs: 2B − B = {verdict['gain']:+.3f}\n"
                             f"{'enough' if verdict['enough'] else 'grow the budget'} (tolerance {verdict['tolerance']:g})",
                    ha="center", fontsize=8)
    ax.set_xticks([t for k in range(len(nets)) for t in (k - 0.15, k + 0.15)],
                  [f"{n}\nB" if i == 0 else "2B" for n in nets for i in range(2)])
    ax.set_ylabel("test mAP@0.5 at EV 0 (one point per seed)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
