"""Result-folder schema: the reader accepts a well-formed results.json and refuses others by name;
both charts draw the summary's means and the contrasts' paired differences."""
from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from workbench.errors import InputFileError
from workbench.experiments.results import draw_results, read_results, result_folders


def make_doc(kind: str, nets=("mobile",), seeds=3) -> dict:
    summary = []
    rng = np.random.default_rng(1)
    for net in nets:
        if kind == "isp":
            for rep, m in (("raw", 0.5), ("linear", 0.55), ("srgb", 0.6)):
                summary.append({"net": net, "representation": rep, "condition": "ev0_trained", "test_ev": 0.0,
                                "n": seeds, "mean_map": m, "sd": 0.02, "ci95_low": m - 0.05, "ci95_high": m + 0.05})
        else:
            for cond in ("ev0_trained", "ev_mix", "per_ev"):
                for ev in (-4.0, -2.0, 0.0, 2.0, 4.0):
                    m = float(0.6 - 0.03 * abs(ev) + 0.02 * rng.random())
                    summary.append({"net": net, "representation": "srgb", "condition": cond, "test_ev": ev,
                                    "n": seeds, "mean_map": m, "sd": 0.02, "ci95_low": m - 0.04,
                                    "ci95_high": m + 0.04})
    contrasts = []
    for net in nets:
        names = (("raw − srgb", 0.0), ("linear − srgb", 0.0)) if kind == "isp" else \
            tuple(("ev_mix − ev0_trained", ev) for ev in (-4.0, -2.0, 0.0, 2.0, 4.0)) + (("under − over", 2.0),)
        for k, (name, ev) in enumerate(names):
            d = 0.01 * (k + 1) * (1 if net == "mobile" else -1)
            contrasts.append({"contrast": name, "net": net, "test_ev": ev, "mean": d, "n": seeds, "sd": 0.01,
                              "t_low": d - 0.02, "t_high": d + 0.02, "boot_low": d - 0.03, "boot_high": d + 0.03})
    return {"format": "camera-workbench-experiment", "schema_version": 3, "kind": kind, "project": "test",
            "profile": "quick", "complete": True, "settings": {"seeds": seeds}, "runs": [], "summary": summary,
            "contrasts": contrasts, "per_ev_is_upper_bound": False}


def write(folder, doc):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(doc))
    return folder


def test_read_and_draw_isp_bars(tmp_path):
    doc = read_results(write(tmp_path / "isp", make_doc("isp", nets=("mobile", "resnet18"))))
    fig = Figure()
    draw_results(fig, doc)
    ax = fig.axes[0]
    heights = sorted(round(p.get_height(), 3) for p in ax.patches)
    assert heights == [0.5, 0.5, 0.55, 0.55, 0.6, 0.6]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["mobile", "resnet18"]
    assert len(ax.lines) > 0                               # error bars
    diffs = fig.axes[1]
    points = sorted(tuple(np.round(xy, 3)) for line in diffs.lines for xy in line.get_xydata()
                    if line.get_marker() == "o")
    # raw − srgb at x≈0 and linear − srgb at x≈1; mobile +0.01/+0.02, resnet18 −0.01/−0.02
    assert points == [(-0.075, 0.01), (0.075, -0.01), (0.925, 0.02), (1.075, -0.02)]


def test_isp_chart_of_an_unfinished_experiment_says_its_seeds(tmp_path):
    """A one-seed bar has no interval to draw: no error bar (not a zero-length one that reads as a
    tight interval); every bar carries its seed count and the differences' legend the paired seeds."""
    doc = make_doc("isp", nets=("mobile",), seeds=2)
    for row in doc["summary"]:
        if row["representation"] != "srgb":
            row.update(n=1, sd=None, ci95_low=None, ci95_high=None)
    for row in doc["contrasts"]:
        row.update(n=1, sd=None, t_low=None, t_high=None)
    doc = read_results(write(tmp_path / "isp", doc))
    fig = Figure()
    draw_results(fig, doc)
    ax = fig.axes[0]
    caps = [y for line in ax.lines for _, y in line.get_xydata()]
    np.testing.assert_allclose(sorted(caps), [0.55, 0.65])    # the sRGB bar's interval alone: 0.6 ± 0.05
    assert sorted(t.get_text() for t in ax.texts) == ["n=1", "n=1", "n=2"]
    assert [t.get_text() for t in fig.axes[1].get_legend().get_texts()] == ["mobile, n=1"]
    # one net: its points centred on their contrasts' ticks, half a slot from the frame
    points = [tuple(xy) for line in fig.axes[1].lines for xy in line.get_xydata() if line.get_marker() == "o"]
    assert sorted(round(x, 3) for x, _ in points) == [0.0, 1.0]
    assert fig.axes[1].get_xlim() == (-0.5, 1.5)


def test_read_and_draw_exposure_curves(tmp_path):
    doc = read_results(write(tmp_path / "exp", make_doc("exposure", nets=("mobile", "resnet18"))))
    fig = Figure()
    draw_results(fig, doc)
    assert len(fig.axes) == 4                              # a curve panel per net, two difference panels
    curves = [line for line in fig.axes[0].lines if len(line.get_xdata()) == 5]
    assert len(curves) == 3 and list(curves[0].get_xdata()) == [-4, -2, 0, 2, 4]
    ev0 = sorted((r["test_ev"], r["mean_map"]) for r in doc["summary"]
                 if r["net"] == "mobile" and r["condition"] == "ev0_trained")
    np.testing.assert_allclose(np.asarray(curves[0].get_ydata(), float), [m for _, m in ev0])
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["trained at EV 0, n=3", "trained on the EV mix, n=3", "trained at that EV, n=3"]   # not an upper bound
    mix = [line for line in fig.axes[2].lines if line.get_marker() == "o"]
    mobile = next(line for line in mix if line.get_color() == "tab:blue")
    np.testing.assert_allclose(np.asarray(mobile.get_ydata(), float), [0.01, 0.02, 0.03, 0.04, 0.05])


def test_result_folders_finds_nested(tmp_path):
    write(tmp_path / "a", make_doc("isp"))
    write(tmp_path / "b" / "c", make_doc("exposure"))
    assert result_folders(tmp_path) == [tmp_path / "a", tmp_path / "b" / "c"]


@pytest.mark.parametrize("change, fragment", [
    ({"format": "other"}, "format"),
    ({"schema_version": 9}, "schema_version"),
    ({"kind": "speed"}, "kind"),
    ({"summary": [{"net": "x"}]}, "summary"),
    ({"contrasts": "none"}, "contrasts"),
    ({"runs": "notalist"}, "runs"),
])
def test_bad_results_refused_with_the_file_named(tmp_path, change, fragment):
    folder = write(tmp_path / "bad", make_doc("isp") | change)
    with pytest.raises(InputFileError, match=fragment) as info:
        read_results(folder)
    assert str(folder / "results.json") in str(info.value)


def test_missing_and_malformed(tmp_path):
    with pytest.raises(InputFileError, match="results.json"):
        read_results(tmp_path)
    (tmp_path / "results.json").write_text("{not json")
    with pytest.raises(InputFileError, match="JSON"):
        read_results(tmp_path)
