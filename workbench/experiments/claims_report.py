"""The paper's four claims against the results of both detection experiments, as a Markdown table
(`workbench experiment claims --isp DIR --exposure DIR`)."""
from __future__ import annotations

from pathlib import Path

from workbench.errors import InputFileError
from workbench.experiments.analysis import ALPHA, EQUIVALENCE_MARGIN, claims
from workbench.experiments.results import read_results


def _interval(part: dict) -> str:
    """The mean with the two-level interval the verdict reads, then the descriptive ones."""
    if part.get("mean") is None:
        return "—"
    shown = [(name, part.get(f"{key}_low"), part.get(f"{key}_high"))
             for name, key in (("**both**", "h"), ("seeds", "t"), ("test set", "boot"))]
    return f"{part['mean']:+.3f} (" + "; ".join(f"{name} [{lo:+.3f}, {hi:+.3f}]" for name, lo, hi in shown
                                                if lo is not None) + ")"


def _p(value) -> str:
    return "—" if value is None else f"{value:.4f}"


def _read_pair(isp_dir: str | Path, exposure_dir: str | Path) -> tuple[dict, dict]:
    """The two result folders' documents, each checked to be of its kind."""
    isp, exposure = read_results(isp_dir), read_results(exposure_dir)
    for doc, kind, folder in ((isp, "isp", isp_dir), (exposure, "exposure", exposure_dir)):
        if doc["kind"] != kind:
            raise InputFileError(folder, f"holds the {doc['kind']} experiment, not the {kind} one")
    return isp, exposure


def claims_markdown(isp_dir: str | Path, exposure_dir: str | Path) -> str:
    """One table row per part of each claim: what is tested, the paired mean difference with its
    two-level 95 % interval (the one the verdict reads) and the descriptive seed and test-set ones,
    the part's p-value, its p-value against (Holm-adjusted over the claim's parts), and the verdict;
    above it, a line for each folder that is not complete yet (its runs and seeds)."""
    docs = dict(zip((isp_dir, exposure_dir), _read_pair(isp_dir, exposure_dir)))
    lines = []
    for folder, doc in docs.items():
        if not doc.get("complete", True):
            seeds = sorted({run["role"]["seed"] for run in doc["runs"] if isinstance(run.get("role"), dict)})
            lines += [f"**Incomplete:** `{Path(folder).name}` holds {len(doc['runs'])} finished runs (seeds "
                      f"{', '.join(map(str, seeds)) or 'none'} of {doc.get('settings', {}).get('seeds', '?')}); "
                      "the verdicts below read only those.", ""]
    lines += ["| claim (paper) | tested as | paired difference (95 % intervals) | p | p against (Holm) | verdict |",
              "|---|---|---|---|---|---|"]
    for claim in claims(docs[isp_dir]["contrasts"], docs[exposure_dir]["contrasts"]):
        for k, part in enumerate(claim["parts"]):
            head = f"{claim['claim']}. {claim['text']} — **{claim['verdict']}**" if k == 0 else ""
            against = None if part["p_against"] is None else part["p_against_holm"]
            lines.append(f"| {head} | {part['text']} | {_interval(part)} | {_p(part['p'])} | {_p(against)} "
                         f"| {part['verdict']} |")
    lines.append("")
    stuck = [(folder, run) for folder, doc in docs.items() for run in doc["runs"]
             if run["train"].get("converged") is not True]
    if stuck:
        lines.append("Runs that did not converge (engine.convergence), read in the contrasts above: " + "; ".join(
            f"{run['key']} ({run['train'].get('convergence') or 'no convergence record'})" for _, run in stuck) + ".")
    else:
        lines.append("Every run read here converged (train mAP ≥ the floor, < 0.03 gained over the second half).")
    lines.append("")
    lines.append(f"Verdicts read the two-level interval (\"both\": seeds and test frames resampled together) "
                 f"and its one-sided p-values at level {ALPHA}. A part is supported when p ≤ {ALPHA}, and a claim "
                 f"when all its parts are; a part is not supported when its p-value of lying on the wrong side, "
                 f"Holm-adjusted over the claim's parts, is ≤ {ALPHA}; otherwise not resolved. A \"≠ 0\" part's p "
                 f"is Holm over its two directions. \"Not much worse\" and \"small cost\" mean within "
                 f"{EQUIVALENCE_MARGIN} mAP.")
    return "\n".join(lines) + "\n"
