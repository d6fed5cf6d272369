"""Charts of the detection experiments, drawn from a results document (results.json) alone, so
the GUI and the command line show the same figures: ISP stage → bars of mean mAP per
representation with 95 % interval error bars, one group per network (the paper's Fig. 5);
exposure → mAP against test EV per network, with 95 % bands, the per-EV upper bound shaded above
(the paper's Fig. 7)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

STYLE = {"ev0_trained": ("trained at EV 0", "-", "tab:blue"),
         "ev_mix": ("trained on the EV mix", "--", "tab:orange"),
         "per_ev": ("trained at each EV (upper bound)", ":", "tab:gray")}
REP_COLOURS = {"raw": "tab:gray", "linear": "tab:green", "srgb": "tab:purple"}


def _errors(rows):
    lo = [r["mean_map"] - r["ci95_low"] if r["ci95_low"] is not None else 0.0 for r in rows]
    hi = [r["ci95_high"] - r["mean_map"] if r["ci95_high"] is not None else 0.0 for r in rows]
    return np.array([lo, hi])


def draw_isp(ax, summary: list[dict]) -> None:
    """Grouped bars: networks along x, one bar per representation, 95 % error bars."""
    nets = sorted({r["net"] for r in summary})
    reps = [r for r in REP_COLOURS if any(s["representation"] == r for s in summary)]
    width = 0.8 / max(len(reps), 1)
    for k, rep in enumerate(reps):
        rows = [next((s for s in summary if s["net"] == n and s["representation"] == rep), None) for n in nets]
        xs = [i + (k - (len(reps) - 1) / 2) * width for i, r in enumerate(rows) if r]
        rows = [r for r in rows if r]
        ax.bar(xs, [r["mean_map"] for r in rows], width, yerr=_errors(rows), capsize=4,
               color=REP_COLOURS[rep], label=rep)
    ax.set_xticks(range(len(nets)), nets)
    ax.set_ylabel("mAP@0.5 (mean over seeds, 95 % CI)")
    ax.set_ylim(0, 1)
    ax.legend(title="trained and tested on")


def draw_exposure(ax, summary: list[dict], net: str) -> None:
    """mAP against test EV for one network: the three training conditions with 95 % bands."""
    for cond, (label, ls, colour) in STYLE.items():
        rows = sorted((s for s in summary if s["net"] == net and s["condition"] == cond), key=lambda s: s["test_ev"])
        if not rows:
            continue
        ev = np.array([r["test_ev"] for r in rows])
        mean = np.array([r["mean_map"] for r in rows])
        ax.plot(ev, mean, ls, color=colour, marker="o", ms=3, label=label)
        if all(r["ci95_low"] is not None for r in rows):
            ax.fill_between(ev, [r["ci95_low"] for r in rows], [r["ci95_high"] for r in rows], color=colour,
                            alpha=0.15, lw=0)
        if cond == "per_ev":
            ax.fill_between(ev, mean, 1.0, color="0.85", alpha=0.5, lw=0, label="unreachable (above the bound)")
    ax.set_xlabel("exposure bias at test (EV)")
    ax.set_ylabel("mAP@0.5")
    ax.set_ylim(0, 1)
    ax.set_title(net)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def plot_experiment(doc: dict, path_png: str | Path) -> Path:
    """Draw the chart of a results document (kind 'isp' or 'exposure') to a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = doc["summary"]
    title = f"{doc['project']} — {doc['kind']} experiment, profile {doc['profile']}, {doc['settings']['seeds']} seed(s)"
    if doc["kind"] == "isp":
        fig, ax = plt.subplots(figsize=(6, 4))
        draw_isp(ax, summary)
        axes = [ax]
    else:
        nets = sorted({s["net"] for s in summary})
        fig, axes = plt.subplots(1, len(nets), figsize=(5.5 * len(nets), 4), squeeze=False)
        axes = list(axes[0])
        for ax, net in zip(axes, nets):
            draw_exposure(ax, summary, net)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = Path(path_png)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)
    return path
