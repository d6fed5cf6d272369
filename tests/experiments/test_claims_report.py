"""The claims table shows the interval and p-value each verdict reads."""
from __future__ import annotations

import json

import numpy as np

from workbench.experiments.analysis import CLAIM_BOUNDS
from workbench.experiments.claims_report import claims_markdown
from workbench.experiments.paired import paired_difference
from workbench.experiments.results import RESULTS_FORMAT, RESULTS_SCHEMA_VERSION


def _folder(root, kind, contrasts, **extra):
    folder = root / kind
    folder.mkdir()
    doc = {"format": RESULTS_FORMAT, "schema_version": RESULTS_SCHEMA_VERSION, "kind": kind, "summary": [],
           "contrasts": contrasts, "runs": [], **extra}
    (folder / "results.json").write_text(json.dumps(doc), encoding="utf-8")
    return folder


def test_claims_table_shows_two_level_interval_and_p(tmp_path):
    drop = np.array([-0.20, -0.25, -0.22, -0.18, -0.21])          # resnet18 − mobile relative drop per seed
    boot = drop[:, None] + np.linspace(-0.02, 0.02, 100)[None, :]
    iv = paired_difference(drop, np.zeros(5), boot, np.zeros_like(boot), CLAIM_BOUNDS)
    row = {"contrast": "relative drop resnet18 − mobile", "net": "both", "test_ev": "all", **iv.to_dict()}
    text = claims_markdown(_folder(tmp_path, "isp", []), _folder(tmp_path, "exposure", [row]))
    line = next(x for x in text.splitlines() if x.startswith("| 1."))
    assert "**supported**" in line
    assert f"**both** [{iv.h_low:+.3f}, {iv.h_high:+.3f}]" in line and f"seeds [{iv.t_low:+.3f}" in line
    assert f"| {1 / 4001:.4f} | 1.0000 | supported |" in line       # every draw below 0; none above
    assert "p_values" not in row                                       # flat, one p_key column each


def test_claims_read_on_unfinished_folders_say_so(tmp_path):
    """Claims can be read while runs are still owed (sittings commit them as they finish); the table
    then says which folder is incomplete and how far it got, so no reader takes it for the result."""
    text = claims_markdown(_folder(tmp_path, "isp", [], complete=False, settings={"seeds": 5}),
                           _folder(tmp_path, "exposure", [], complete=True))
    lines = text.splitlines()
    assert lines[0] == "**Incomplete:** `isp` holds 0 finished runs (seeds none of 5); the verdicts below read only those."
    assert not any("`exposure`" in x for x in lines)
    assert lines[2].startswith("| claim (paper) |")
