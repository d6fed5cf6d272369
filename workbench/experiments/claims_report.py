"""The paper's four claims against the results of both detection experiments, as a Markdown table
(`workbench experiment claims --isp DIR --exposure DIR`)."""
from __future__ import annotations

from pathlib import Path

from workbench.errors import InputFileError
from workbench.experiments.analysis import EQUIVALENCE_MARGIN, claims
from workbench.experiments.results import read_results


def _interval(part: dict) -> str:
    if part.get("mean") is None:
        return "—"
    t = ("" if part.get("t_low") is None else f"seeds [{part['t_low']:+.3f}, {part['t_high']:+.3f}]")
    b = ("" if part.get("boot_low") is None else f"test set [{part['boot_low']:+.3f}, {part['boot_high']:+.3f}]")
    return f"{part['mean']:+.3f} ({'; '.join(x for x in (t, b) if x)})"


def claims_of(isp_dir: str | Path, exposure_dir: str | Path) -> list[dict]:
    """claims() of the two result folders (each checked to be of its kind)."""
    isp, exposure = read_results(isp_dir), read_results(exposure_dir)
    for doc, kind, folder in ((isp, "isp", isp_dir), (exposure, "exposure", exposure_dir)):
        if doc["kind"] != kind:
            raise InputFileError(folder, f"holds the {doc['kind']} experiment, not the {kind} one")
    return claims(isp["contrasts"], exposure["contrasts"])


def claims_markdown(isp_dir: str | Path, exposure_dir: str | Path) -> str:
    """One table row per part of each claim: what is tested, the paired mean difference with its
    seed and test-set 95 % intervals, and the verdict."""
    lines = ["| claim (paper) | tested as | paired difference (95 % intervals) | verdict |",
             "|---|---|---|---|"]
    for claim in claims_of(isp_dir, exposure_dir):
        for k, part in enumerate(claim["parts"]):
            head = f"{claim['claim']}. {claim['text']} — **{claim['verdict']}**" if k == 0 else ""
            lines.append(f"| {head} | {part['text']} | {_interval(part)} | {part['verdict']} |")
    lines.append("")
    lines.append(f"A part is supported when both intervals lie on its side of its bound, not supported when both "
                 f"lie on the other side, not resolved otherwise. \"Not much worse\" and \"small cost\" mean "
                 f"within {EQUIVALENCE_MARGIN} mAP.")
    return "\n".join(lines) + "\n"
