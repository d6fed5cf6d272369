"""Is a training budget enough? The 'budget' experiment's reading (experiments.detection).

Per net, runs trained on sRGB at EV 0 on the same seeds are tested at EV 0 at a ladder of
budgets: the profile's B and 2B (budget_factor 1 and 2), and the earlier steps B/2, B/4, … that
the folder kept when the budget grew (plan.budget_ladder_configs). Each step e → 2e is read as the
gain of test mAP@0.5, paired by seed (workbench.experiments.paired); a step is decided when it
has BUDGET_SEEDS seeds, and e is enough for the net when the mean gain over them is below the
tolerance (a run that loses with more training counts as enough), else the budget must grow.
With 2 seeds the intervals are wide: the rule reads the mean, as the study asks. The chosen
budget is the profile's B: it is settled when its step is decided and enough and every decided
step below it is not (B is the first step whose gain is below the tolerance).
"""
from __future__ import annotations

from workbench.experiments.analysis import _paired, seed_values
from workbench.experiments.paired import t_interval
from workbench.experiments.plan import BUDGET_SEEDS


def _at0(maps):
    return maps[0.0]


def _status(steps: list[dict], budget: int | None) -> str:
    """The profile's budget B against the ladder: 'settled' (its step decided and enough, none
    below it enough), 'grow' (decided, not enough), 'open' (not decided) or 'too large' (a decided
    step below B is enough already)."""
    own = next((s for s in steps if s["epochs"] == budget), None)
    if any(s["decided"] and s["enough"] for s in steps if s["epochs"] < (budget or 0)):
        return "too large"
    if own is None or not own["decided"]:
        return "open"
    return "settled" if own["enough"] else "grow"


def _text(status: str, own: dict | None, tolerance: float) -> str:
    """The verdict on the profile's budget B in words."""
    if status == "settled":
        return f"settled: B → 2B gains {own['gain']:+.3f} < {tolerance:g}, the first step that does"
    if status == "grow":
        return f"not settled: B → 2B gains {own['gain']:+.3f} ≥ {tolerance:g}, the budget grows to 2B"
    if status == "too large":
        return f"B is more than needed: a step below it gains < {tolerance:g}"
    return f"not settled yet: B → 2B has {len(own['seeds']) if own else 0} of {BUDGET_SEEDS} seeds"


def budget_analysis(runs: list[dict], boots: dict, tolerance: float, epochs: dict | None = None) -> dict:
    """summary (mean test mAP at EV 0 per net and epochs), contrasts ('2B − B' per net and step,
    'epochs' its B) and budget_enough ({net: the profile's step as epochs B, gain, seeds, enough,
    tolerance; its status and text; and 'ladder', every step e → 2e the runs hold}). epochs: the
    profile's budget per net (default: that of the runs in budget_factor 1)."""
    summary, rows, enough = [], [], {}
    for net in sorted({r["role"]["net"] for r in runs}):
        mine = [r for r in runs if r["role"]["net"] == net]
        budget = (epochs or {}).get(net) or next((r["config"]["epochs"] for r in mine
                                                   if r["role"].get("budget_factor") == 1), None)
        values = {e: seed_values([r for r in mine if r["config"]["epochs"] == e], boots, _at0, net=net)
                  for e in sorted({r["config"]["epochs"] for r in mine})}
        for e, (seeds, points, _) in values.items():
            mean, sd, lo, hi = t_interval(points)
            summary.append({"net": net, "representation": "srgb", "condition": f"budget ×{e / budget:g}" if budget
                            else f"{e} epochs", "test_ev": 0.0, "epochs": e, "n": len(seeds), "mean_map": mean,
                            "sd": sd, "ci95_low": lo, "ci95_high": hi, "per_seed": dict(zip(seeds, points.tolist()))})
        steps = []
        for e in values:
            interval = _paired(values[2 * e], values[e]) if 2 * e in values else None      # 2e − e, shared seeds
            if interval is None:
                continue
            rows.append({"contrast": "2B − B", "net": net, "test_ev": 0.0, "epochs": e, **interval.to_dict()})
            seeds = sorted(set(values[2 * e][0]) & set(values[e][0]))
            steps.append({"epochs": e, "to_epochs": 2 * e, "gain": interval.mean, "seeds": seeds,
                          "enough": interval.mean < tolerance, "decided": len(seeds) >= BUDGET_SEEDS})
        status = _status(steps, budget)
        own = next((s for s in steps if s["epochs"] == budget), None)
        enough[net] = {**({k: own[k] for k in ("epochs", "gain", "seeds", "enough")} if own else
                          {"epochs": budget, "gain": None, "seeds": [], "enough": None}),
                       "tolerance": tolerance, "status": status, "text": _text(status, own, tolerance),
                       "ladder": steps}
    return {"summary": summary, "contrasts": rows, "per_ev_is_upper_bound": None, "budget_enough": enough}


def settled_nets(budget_enough: dict) -> list[str]:
    """The nets of a budget study's `budget_enough` whose budget B is settled: their ISP and exposure
    runs can start at B while another net's study still trains (packaging/standard-results.sh)."""
    return [net for net, verdict in budget_enough.items() if verdict.get("status") == "settled"]


def _verdict_text(verdict: dict) -> str:
    """The verdict's text; for a folder written before the ladder (no 'text'), its B → 2B gain."""
    if "text" in verdict:
        return verdict["text"]
    if verdict.get("gain") is None:
        return "no step yet"
    return (f"B → 2B gains {verdict['gain']:+.3f} on {len(verdict['seeds'])} seed(s): "
            f"{'enough' if verdict['enough'] else 'grow the budget'}")


def draw_budget(fig, doc: dict) -> None:
    """Per net, test mAP at EV 0 against training epochs (log scale) over the whole ladder: one line
    per seed, each step's mean gain 2e − e above it, the profile's budget B marked (2B shown even
    before it is run), and the verdict in the title."""
    nets = sorted({s["net"] for s in doc["summary"]})
    budgets = (doc.get("settings") or {}).get("epochs", {})
    for k, net in enumerate(nets):
        ax = fig.add_subplot(1, len(nets), k + 1)
        rows = sorted((s for s in doc["summary"] if s["net"] == net), key=lambda s: s["epochs"])
        colour = "tab:blue" if net == "mobile" else "tab:red"
        for j, seed in enumerate(sorted({seed for r in rows for seed in r.get("per_seed", {})}, key=str)):
            points = [(r["epochs"], r["per_seed"][seed]) for r in rows if seed in r.get("per_seed", {})]
            ax.plot(*zip(*points), "os^Dv"[j % 5] + "-", color=colour, alpha=0.75, label=f"seed {seed}")
        verdict = doc.get("budget_enough", {}).get(net, {})
        for step in verdict.get("ladder", []):
            n = len(step["seeds"])
            ax.text((step["epochs"] * step["to_epochs"]) ** 0.5, 0.93,
                    f"{step['gain']:+.3f}\n({n} seed{'s' * (n != 1)})", ha="center", va="top", fontsize=7)
        budget = budgets.get(net, verdict.get("epochs"))
        ticks = sorted({r["epochs"] for r in rows} | ({budget, 2 * budget} if budget else set()))
        if budget:
            ax.axvline(budget, color="k", lw=0.8, ls="--")
            ax.text(budget, 0.03, "profile's B ", fontsize=7, ha="right")
        ax.set_xscale("log", base=2)
        ax.set_xlim(ticks[0] / 1.4, ticks[-1] * 1.4)
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_xlabel("training epochs (gain 2e − e above each step)")
        ax.set_title(f"{net}, B = {budget} epochs\n{_verdict_text(verdict)}", fontsize=8)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.axes[0].set_ylabel("test mAP@0.5 at EV 0")
