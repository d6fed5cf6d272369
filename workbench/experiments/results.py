"""Result folders of the detection experiments: their JSON schema, readers, and the charts drawn
on any matplotlib Figure (the GUI's experiments panel and the command line).

A result folder holds `results.json` (this schema), `runs.csv`, `summary.csv`, `contrasts.csv`,
`bootstrap.npz` (each run's test-set bootstrap resamples of its mAPs), `project.json` (the project
the runs read) and a chart PNG.

results.json (schema_version 3):

    {
      "format": "camera-workbench-experiment",     # required, exactly this
      "schema_version": 3,                          # required
      "kind": "isp" | "exposure" | "budget",        # required
      "project": str, "profile": "quick" | "standard" | "paper" | str,
      "complete": bool,                             # false while runs are still to come
      "classes": [str, ...], "ev_biases": [float, ...],
      "settings": {"seeds": int, ...},              # the profile used (epochs, image size, nets, …)
      "code_version": str,                          # the code that wrote it (git describe)
      "dataset": {"folder": str (its name), "fingerprint": str, "split_digest": str, "frames": int,
                  "stats": {...}},
      "runs": [{"key": str, "role": {"net", "representation", "condition", "seed"[, "train_ev"]
                                     [, "budget_factor"]},
                "config": {...}, "train": {... "train_map", "curve", "history", "train_map_half",
                                          "train_map_end", "half_gain", "converged", "convergence" ...},
                "tests": [{"ev": float, "map": float | null, "ap": {class: float}, ...}, ...],
                "machine": {"cpu", "bf16_native", "threads", "wall_s", "cpu_s", "code_version"},
                "digest": str, "checksum": str}, ...],     # since issue 34 (experiments.records); each
                                                          # test carries a "checksum" too
      "superseded_runs": [run, ...],                # records an earlier profile planned, outside the analysis
                                                    # (a budget folder keeps earlier budgets in 'runs',
                                                    # budget_factor 1/2, 1/4, …: its ladder)
      "checksum": str,                              # since issue 34: of the rest of the document
      "summary": [                                  # required; what the main charts draw
        {"net": str, "representation": "raw" | "linear" | "srgb",
         "condition": "ev0_trained" | "ev_mix" | "per_ev", "test_ev": float, "n": int,
         "mean_map": float, "sd": float | null,
         "ci95_low", "ci95_high": float | null,     # seed (Student t) interval of the mean
         "boot_low", "boot_high": float | null}, ...],  # test-set bootstrap interval of the mean
      "contrasts": [                                # required; paired differences (analysis.py)
        {"contrast": str, "net": str, "test_ev": float | "all", "mean": float, "n": int, "sd",
         "t_low", "t_high", "boot_low", "boot_high",  # seed t and test-set intervals (descriptive)
         "h_low", "h_high": float | null,          # two-level interval (seeds, then test frames)
         "p_above_+0", ...: float | null}, ...],    # its one-sided p-values at the claims' bounds
      "per_ev_is_upper_bound": bool | null,
      "budget_enough": {net: {"epochs", "gain", "seeds", "enough", "tolerance",  # 'budget' only: the
                              "status", "text", "ladder": [{"epochs", "to_epochs", "gain", "seeds",
                                                           "enough", "decided"}, ...]}}  # profile's step,
                                                          # its verdict and every step (budget.py)
    }

Charts: 'isp' → bars of mean mAP per representation per network with both intervals, beside the
paired differences raw − sRGB and linear − sRGB; 'exposure' → mAP against test EV per network
(one curve per training condition, seed bands), over the paired differences EV mix − EV-0-trained,
under − over exposure and (both nets) the relative drop of resnet18 − mobile; 'budget' → per net,
test mAP against epochs over the whole ladder (B/2, B, 2B, …) per seed, each step's gain, the
profile's B and its verdict. In the difference panels a thick bar is the seed interval
and a thin one the two-level interval (seeds and test frames).
"""
from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np

from workbench.datasets.files import read_json_object
from workbench.errors import InputFileError

RESULTS_FORMAT = "camera-workbench-experiment"
RESULTS_SCHEMA_VERSION = 3
RESULTS_FILE = "results.json"
BOOTSTRAP_FILE = "bootstrap.npz"
MAX_RESULTS_BYTES = 64 * 2 ** 20
KINDS = ("isp", "exposure", "budget")
SUMMARY_KEYS = ("net", "representation", "condition", "test_ev", "mean_map", "ci95_low", "ci95_high")
CONTRAST_KEYS = ("contrast", "net", "test_ev", "mean", "t_low", "t_high", "boot_low", "boot_high")
REP_COLOURS = {"raw": "tab:gray", "linear": "tab:green", "srgb": "tab:purple"}
NET_COLOURS = {"mobile": "tab:blue", "resnet18": "tab:red", "both": "k"}


def condition_style(doc: dict) -> dict:
    """Label, line style and colour of each exposure condition; the per-EV curve is called an
    upper bound only where the document found it one for every seed."""
    per_ev = ("trained at each EV (upper bound)" if doc.get("per_ev_is_upper_bound")
              else "trained at that EV")
    return {"ev0_trained": ("trained at EV 0", "-", "tab:blue"),
            "ev_mix": ("trained on the EV mix", "--", "tab:orange"),
            "per_ev": (per_ev, ":", "tab:gray")}


def _rows_ok(rows, keys) -> bool:
    return isinstance(rows, list) and all(isinstance(r, dict) and all(k in r for k in keys) for r in rows)


def read_results(path: str | Path) -> dict:
    """The results document of a result folder (or of a results.json path), checked against the
    schema above and its records against the plan (experiments.records.check_runs); errors name
    the file (and the run) and what is wrong."""
    p = Path(path)
    if p.is_dir():
        p = p / RESULTS_FILE
    doc = read_json_object(p, "experiment results file", "no such file: a result folder holds results.json",
                           MAX_RESULTS_BYTES)
    if doc.get("format") != RESULTS_FORMAT:
        raise InputFileError(p, f"not an experiment results file (format must be '{RESULTS_FORMAT}')")
    if doc.get("schema_version") != RESULTS_SCHEMA_VERSION:
        raise InputFileError(p, f"schema_version {doc.get('schema_version')!r}; this workbench reads "
                                f"{RESULTS_SCHEMA_VERSION} (rerun the experiment into a new folder)")
    if doc.get("kind") not in KINDS:
        raise InputFileError(p, f"kind {doc.get('kind')!r}; allowed: {', '.join(KINDS)}")
    if not _rows_ok(doc.get("summary"), SUMMARY_KEYS):
        raise InputFileError(p, f"'summary' must be a list of rows with {', '.join(SUMMARY_KEYS)}")
    if not _rows_ok(doc.get("contrasts"), CONTRAST_KEYS):
        raise InputFileError(p, f"'contrasts' must be a list of rows with {', '.join(CONTRAST_KEYS)}")
    if not isinstance(doc.get("runs"), list):
        raise InputFileError(p, "'runs' must be a list")
    _check_numbers(p, doc)
    from workbench.experiments.records import check_runs, document_problem
    check_runs(p, doc)
    problem = document_problem(doc)
    if problem is not None:
        raise InputFileError(p, problem)
    return doc


def _is_number(value, low: float = -math.inf, high: float = math.inf) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and low <= value <= high \
        and math.isfinite(value)


def _check_numbers(p: Path, doc: dict) -> None:
    """The summary's means are mAPs in 0…1; its intervals and the contrasts' numbers are finite
    (or None where an interval needs two seeds); test EVs are numbers."""
    for row in doc["summary"]:
        if not (_is_number(row["mean_map"], 0.0, 1.0) and _is_number(row["test_ev"]) and all(
                row.get(k) is None or _is_number(row[k]) for k in ("ci95_low", "ci95_high", "boot_low", "boot_high"))):
            raise InputFileError(p, f"a summary row ({str(row.get('net'))[:40]}, {str(row.get('condition'))[:40]}) "
                                    "holds a mean that is not a mAP in 0…1 or an interval that is not a number")
    for row in doc["contrasts"]:
        if not (_is_number(row["mean"]) and (row["test_ev"] == "all" or _is_number(row["test_ev"]))
                and all(row.get(k) is None or _is_number(row[k])
                        for k in ("t_low", "t_high", "boot_low", "boot_high", "h_low", "h_high"))):
            raise InputFileError(p, f"a contrast row ({str(row.get('contrast'))[:40]}) holds a number that is "
                                    "not finite")


def read_bootstraps(folder: str | Path) -> dict:
    """{run key: {test EV: resampled mAPs}} from a result folder's bootstrap.npz ({} when absent)."""
    path = Path(folder) / BOOTSTRAP_FILE
    if not path.exists():
        return {}
    out: dict = {}
    try:
        with np.load(path, allow_pickle=False) as data:
            for name in data.files:
                key, _, ev = name.rpartition("|")
                out.setdefault(key, {})[float(ev)] = np.asarray(data[name], np.float64)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputFileError(path, f"cannot be read ({exc.__class__.__name__}); delete it and the "
                                   "results.json beside it to run the experiment again") from None
    return out


def result_folders(root: str | Path, depth: int = 2) -> list[Path]:
    """Folders at most `depth` levels below root (root included) that hold a results.json."""
    root = Path(root)
    found = [root] if (root / RESULTS_FILE).is_file() else []
    if depth > 0 and root.is_dir():
        for child in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
            found += result_folders(child, depth - 1)
    return found


def _bars(rows: list[dict], low: str, high: str, mean: str = "mean_map") -> np.ndarray:
    lo = [r[mean] - r[low] if r.get(low) is not None else 0.0 for r in rows]
    hi = [r[high] - r[mean] if r.get(high) is not None else 0.0 for r in rows]
    return np.array([lo, hi])


def _top(rows: list[dict]) -> float:
    """Upper y limit: 15 % above the highest mean or interval bound, at most 1 (mAP is a fraction)."""
    values = [v for r in rows for v in (r["mean_map"], r["ci95_high"], r.get("boot_high")) if v is not None]
    return min(1.0, max(0.05, 1.15 * max(values, default=1.0)))


def _seeds_text(rows: list[dict]) -> str:
    """'n=K' or 'n=K–M': the seeds behind a set of rows (their 'n')."""
    ns = sorted({int(r["n"]) for r in rows if r.get("n") is not None})
    return "" if not ns else f"n={ns[0]}" if len(ns) == 1 else f"n={ns[0]}–{ns[-1]}"


def draw_isp(ax, summary: list[dict]) -> None:
    """Grouped bars: networks along x, one bar per representation, its seed count (n) at its
    foot; a seed (cap) interval where there is one (two or more seeds), none where there is not."""
    nets = sorted({r["net"] for r in summary})
    reps = [r for r in REP_COLOURS if any(s["representation"] == r for s in summary)]
    width = 0.8 / max(len(reps), 1)
    for k, rep in enumerate(reps):
        rows = [next((s for s in summary if s["net"] == n and s["representation"] == rep), None) for n in nets]
        xs = [i + (k - (len(reps) - 1) / 2) * width for i, r in enumerate(rows) if r]
        rows = [r for r in rows if r]
        ax.bar(xs, [r["mean_map"] for r in rows], width, color=REP_COLOURS[rep], label=rep)
        with_ci = [(x, r) for x, r in zip(xs, rows) if r.get("ci95_low") is not None]
        if with_ci:
            ax.errorbar([x for x, _ in with_ci], [r["mean_map"] for _, r in with_ci], fmt="none", ecolor="k",
                        yerr=_bars([r for _, r in with_ci], "ci95_low", "ci95_high"), capsize=4)
        for x, r in zip(xs, rows):
            ax.text(x, 0.01, _seeds_text([r]), ha="center", va="bottom", fontsize=7, color="white")
    ax.set_xticks(range(len(nets)), nets)
    ax.set_ylabel("mAP@0.5 (mean over seeds, 95 % seed CI)")
    ax.set_ylim(0, _top(summary))
    ax.legend(title="trained and tested on", fontsize=7, title_fontsize=8, ncol=max(len(reps), 1),
              loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False)   # above the bars, over none


def draw_differences(ax, rows: list[dict], x_of, title: str, xlabel: str | None = None) -> None:
    """Paired differences as points with a thick seed interval and a thin two-level interval (seeds
    and test frames, the one verdicts read; neither with one seed), coloured by net, the legend
    saying how many seeds are paired; x_of(row) places each row; a line at 0."""
    ax.axhline(0.0, color="k", lw=0.8)
    for net in sorted({r["net"] for r in rows}):
        mine = [r for r in rows if r["net"] == net]
        xs = np.array([x_of(r) for r in mine], dtype=float)
        colour = NET_COLOURS.get(net, "tab:green")
        ax.errorbar(xs, [r["mean"] for r in mine], yerr=_bars(mine, "h_low", "h_high", "mean"), fmt="none",
                    ecolor=colour, elinewidth=0.8, capsize=2, alpha=0.7)
        ax.errorbar(xs, [r["mean"] for r in mine], yerr=_bars(mine, "t_low", "t_high", "mean"), fmt="o", ms=4,
                    color=colour, elinewidth=2.5, capsize=0, label=f"{net}, {_seeds_text(mine)}")
    ax.set_title(title, fontsize=9)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3)
    if rows:
        ax.legend(fontsize=7)
    else:
        ax.text(0.5, 0.5, "no paired runs yet", ha="center", va="center", transform=ax.transAxes, color="0.5")


def draw_exposure(ax, summary: list[dict], net: str, styles: dict) -> None:
    """mAP against test EV for one network: one curve per training condition (its seeds, n, in the
    legend), seed bands where every point has one."""
    for cond, (label, ls, colour) in styles.items():
        rows = sorted((s for s in summary if s["net"] == net and s["condition"] == cond), key=lambda s: s["test_ev"])
        if not rows:
            continue
        ev = np.array([r["test_ev"] for r in rows])
        ax.plot(ev, [r["mean_map"] for r in rows], ls, color=colour, marker="o", ms=3,
                label=f"{label}, {_seeds_text(rows)}")
        if all(r["ci95_low"] is not None for r in rows):
            ax.fill_between(ev, [r["ci95_low"] for r in rows], [r["ci95_high"] for r in rows], color=colour,
                            alpha=0.15, lw=0)
    ax.set_xlabel("exposure bias at test (EV)")
    ax.set_ylabel("mAP@0.5")
    ax.set_ylim(0, _top([s for s in summary if s["net"] == net]))
    ax.set_title(net)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def chart_size_in(doc: dict) -> tuple[float, float]:
    """Figure size (inches) that fits the document's chart."""
    if doc["kind"] == "isp":
        return 10.0, 4.0
    if doc["kind"] == "budget":
        return max(6.0, 4.5 * len({s["net"] for s in doc["summary"]})), 4.5
    nets = len({s["net"] for s in doc["summary"]}) or 1
    return max(4.6 * nets, 12.0), 7.5


def draw_results(fig, doc: dict) -> None:
    """The chart of a results document on `fig` (module docstring)."""
    summary, diffs = doc["summary"], doc.get("contrasts", [])
    seeds = doc.get("settings", {}).get("seeds", "?")
    if doc["kind"] == "budget" and isinstance(seeds, int):
        from workbench.experiments.plan import BUDGET_SEEDS
        seeds = min(seeds, BUDGET_SEEDS)             # the study trains its first seeds only
    state = "" if doc.get("complete", True) else " (incomplete)"
    fig.suptitle(f"{doc.get('project', '?')} — {doc['kind']} experiment, profile {doc.get('profile', '?')}, "
                 f"{seeds} seed(s){state}", fontsize=9)
    if not summary:
        fig.add_subplot().text(0.5, 0.5, "no finished runs yet", ha="center", va="center")
        return
    if doc["kind"] == "budget":
        from workbench.experiments.budget import draw_budget
        draw_budget(fig, doc)
        return
    if doc["kind"] == "isp":
        left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
        draw_isp(left, summary)
        rows = [r for r in diffs if r["contrast"] in ("raw − srgb", "linear − srgb")]
        names = ["raw − srgb", "linear − srgb"]
        nets = sorted({r["net"] for r in rows})
        draw_differences(right, rows,
                         lambda r: names.index(r["contrast"]) + 0.15 * (nets.index(r["net"]) - (len(nets) - 1) / 2),
                         "paired difference of mAP (same seed, same test captures)")
        right.set_xticks(range(2), names)
        right.set_xlim(-0.5, len(names) - 0.5)          # half a slot each side: no point on the frame
        return
    nets = sorted({s["net"] for s in summary})
    panels = [("ev_mix − ev0_trained", "EV mix − trained at EV 0", "test EV"),
              ("under − over", "under − over exposure: mAP(−k) − mAP(+k)", "k (EV)")]
    if any(r["contrast"] == "relative drop resnet18 − mobile" for r in diffs):
        panels.append(("relative drop resnet18 − mobile", "relative drop 1 − mAP(EV)/mAP(0): resnet18 − mobile",
                       "test EV"))
    grid = fig.add_gridspec(2, max(len(nets), len(panels)) * 2)
    styles = condition_style(doc)
    span = grid.ncols // len(nets)
    for k, net in enumerate(nets):
        draw_exposure(fig.add_subplot(grid[0, k * span:(k + 1) * span]), summary, net, styles)
    span = grid.ncols // len(panels)
    nets_all = sorted({r["net"] for r in diffs}) or ["mobile"]
    for k, (name, title, xlabel) in enumerate(panels):
        rows = [r for r in diffs if r["contrast"] == name and r["test_ev"] != "all"]
        draw_differences(fig.add_subplot(grid[1, k * span:(k + 1) * span]), rows,
                         lambda r: float(r["test_ev"]) + 0.12 * (nets_all.index(r["net"]) - (len(nets_all) - 1) / 2),
                         title, xlabel)
