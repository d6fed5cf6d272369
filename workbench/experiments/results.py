"""Result folders of the detection experiments: their JSON schema, a reader, and the paper's two
charts drawn on any matplotlib Figure (the GUI's experiments panel and the command line).

A result folder holds `results.json` (this schema), `runs.csv`, `summary.csv` and a chart PNG.

results.json (schema_version 1):

    {
      "format": "camera-workbench-experiment",     # required, exactly this
      "schema_version": 1,                          # required
      "kind": "isp" | "exposure",                   # required
      "project": str, "profile": "quick" | "paper" | str,
      "complete": bool,                             # false while runs are still to come
      "classes": [str, ...],                        # detector classes, e.g. ["car", "person"]
      "ev_biases": [float, ...],                    # the project's experiment.ev_biases
      "settings": {"seeds": int, ...},              # the profile used (epochs, image size, nets, …)
      "dataset": {"folder": str, "fingerprint": str, ...},
      "runs": [                                     # one per trained network
        {"key": str, "role": {"net": str, "representation": str, "condition": str, "seed": int},
         "config": {...}, "train": {...}, "classes": [...],
         "tests": [{"ev": float, "map": float, "ap": {class: float}, ...}, ...]}, ...],
      "summary": [                                  # required; what the charts draw
        {"net": str,                                # e.g. "mobile", "resnet18"
         "representation": "raw" | "linear" | "srgb",
         "condition": "ev0_trained" | "ev_mix" | "per_ev",
         "test_ev": float,                          # exposure bias of the test captures
         "n": int,                                  # seeds averaged
         "mean_map": float,                         # mAP@0.5, 0–1
         "sd": float | null, "ci95_low": float | null, "ci95_high": float | null}, ...]
    }

Charts: kind 'isp' → bars of mean mAP per representation (raw, linear, sRGB) per network with
95 % interval error bars (the paper's Fig. 5); kind 'exposure' → mAP against test EV per network,
one curve per training condition with 95 % bands (the paper's Fig. 7).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from workbench.errors import InputFileError

RESULTS_FORMAT = "camera-workbench-experiment"
RESULTS_SCHEMA_VERSION = 1
RESULTS_FILE = "results.json"
KINDS = ("isp", "exposure")
SUMMARY_KEYS = ("net", "representation", "condition", "test_ev", "mean_map", "ci95_low", "ci95_high")
REP_COLOURS = {"raw": "tab:gray", "linear": "tab:green", "srgb": "tab:purple"}
CONDITION_STYLE = {"ev0_trained": ("trained at EV 0", "-", "tab:blue"),
                   "ev_mix": ("trained on the EV mix", "--", "tab:orange"),
                   "per_ev": ("trained at each EV (upper bound)", ":", "tab:gray")}


def read_results(path: str | Path) -> dict:
    """The results document of a result folder (or of a results.json path), checked against the
    schema above; errors name the file and what is wrong."""
    p = Path(path)
    if p.is_dir():
        p = p / RESULTS_FILE
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputFileError(p, "no such file: a result folder holds results.json") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputFileError(p, f"cannot be read as JSON ({exc.__class__.__name__})") from None
    if not isinstance(doc, dict) or doc.get("format") != RESULTS_FORMAT:
        raise InputFileError(p, f"not an experiment results file (format must be '{RESULTS_FORMAT}')")
    if doc.get("schema_version") != RESULTS_SCHEMA_VERSION:
        raise InputFileError(p, f"schema_version {doc.get('schema_version')!r}; this workbench reads "
                                f"{RESULTS_SCHEMA_VERSION}")
    if doc.get("kind") not in KINDS:
        raise InputFileError(p, f"kind {doc.get('kind')!r}; allowed: {', '.join(KINDS)}")
    summary = doc.get("summary")
    if not isinstance(summary, list) or not all(isinstance(r, dict) and all(k in r for k in SUMMARY_KEYS)
                                                for r in summary):
        raise InputFileError(p, f"'summary' must be a list of rows with {', '.join(SUMMARY_KEYS)}")
    return doc


def result_folders(root: str | Path, depth: int = 2) -> list[Path]:
    """Folders at most `depth` levels below root (root included) that hold a results.json."""
    root = Path(root)
    found = [root] if (root / RESULTS_FILE).is_file() else []
    if depth > 0 and root.is_dir():
        for child in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
            found += result_folders(child, depth - 1)
    return found


def _error_bars(rows: list[dict]) -> np.ndarray:
    lo = [r["mean_map"] - r["ci95_low"] if r["ci95_low"] is not None else 0.0 for r in rows]
    hi = [r["ci95_high"] - r["mean_map"] if r["ci95_high"] is not None else 0.0 for r in rows]
    return np.array([lo, hi])


def _top(rows: list[dict]) -> float:
    """Upper y limit: 15 % above the highest mean or interval bound, at most 1 (mAP is a fraction)."""
    values = [v for r in rows for v in (r["mean_map"], r["ci95_high"]) if v is not None]
    return min(1.0, max(0.05, 1.15 * max(values, default=1.0)))


def draw_isp(ax, summary: list[dict]) -> None:
    """Grouped bars: networks along x, one bar per representation, 95 % error bars."""
    nets = sorted({r["net"] for r in summary})
    reps = [r for r in REP_COLOURS if any(s["representation"] == r for s in summary)]
    width = 0.8 / max(len(reps), 1)
    for k, rep in enumerate(reps):
        rows = [next((s for s in summary if s["net"] == n and s["representation"] == rep), None) for n in nets]
        xs = [i + (k - (len(reps) - 1) / 2) * width for i, r in enumerate(rows) if r]
        rows = [r for r in rows if r]
        ax.bar(xs, [r["mean_map"] for r in rows], width, yerr=_error_bars(rows), capsize=4,
               color=REP_COLOURS[rep], label=rep)
    ax.set_xticks(range(len(nets)), nets)
    ax.set_ylabel("mAP@0.5 (mean over seeds, 95 % CI)")
    ax.set_ylim(0, _top(summary))
    ax.legend(title="trained and tested on")


def draw_exposure(ax, summary: list[dict], net: str) -> None:
    """mAP against test EV for one network: one curve per training condition, 95 % bands."""
    for cond, (label, ls, colour) in CONDITION_STYLE.items():
        rows = sorted((s for s in summary if s["net"] == net and s["condition"] == cond), key=lambda s: s["test_ev"])
        if not rows:
            continue
        ev = np.array([r["test_ev"] for r in rows])
        ax.plot(ev, [r["mean_map"] for r in rows], ls, color=colour, marker="o", ms=3, label=label)
        if all(r["ci95_low"] is not None for r in rows):
            ax.fill_between(ev, [r["ci95_low"] for r in rows], [r["ci95_high"] for r in rows], color=colour,
                            alpha=0.15, lw=0)
    ax.set_xlabel("exposure bias at test (EV)")
    ax.set_ylabel("mAP@0.5")
    ax.set_ylim(0, _top([s for s in summary if s["net"] == net]))
    ax.set_title(net)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def draw_results(fig, doc: dict) -> None:
    """The chart of a results document on `fig`: ISP bars, or one mAP-vs-EV panel per network."""
    summary = doc["summary"]
    seeds = doc.get("settings", {}).get("seeds", "?")
    state = "" if doc.get("complete", True) else " (incomplete)"
    fig.suptitle(f"{doc.get('project', '?')} — {doc['kind']} experiment, profile {doc.get('profile', '?')}, "
                 f"{seeds} seed(s){state}", fontsize=9)
    if not summary:
        fig.add_subplot().text(0.5, 0.5, "no finished runs yet", ha="center", va="center")
        return
    if doc["kind"] == "isp":
        draw_isp(fig.add_subplot(), summary)
        return
    nets = sorted({s["net"] for s in summary})
    for k, net in enumerate(nets):
        draw_exposure(fig.add_subplot(1, len(nets), k + 1), summary, net)
