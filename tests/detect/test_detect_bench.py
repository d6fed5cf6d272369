"""`workbench bench detect` is registered and its rows add up: totals are the sum of their parts,
parameter counts are the built nets', and a training image costs its step plus its view."""
import pytest

from workbench.bench import all_benches
from workbench.bench import detect as bench


def test_detect_bench_rows(monkeypatch):
    from workbench.detect.models import build_detector
    assert "detect" in all_benches().names
    views = bench._view_rows(48, 64, 1)
    assert [r["what"] for r in views] == ["raw", "linear", "srgb"]
    assert views[0]["isp_ms"] == 0.0 and views[1]["isp_ms"] > 0
    for r in views:
        assert r["total_ms_per_image"] == pytest.approx(r["sensor_ms"] + r["isp_ms"] + r["input_ms"])
    nets = bench._network_rows(32, 48, 1, "cpu")
    assert {r["what"] for r in nets} == {"mobile srgb", "mobile raw", "resnet18 srgb", "resnet18 raw"}
    for r in nets:
        name, rep = r["what"].split()
        net = build_detector(name, 4 if rep == "raw" else 3, bench.NUM_CLASSES, 2 if rep == "raw" else 1)
        assert r["params_M"] == pytest.approx(sum(p.numel() for p in net.parameters()) / 1e6)
        assert r["train_ms_per_image"] > r["infer_ms_per_image"] > 0          # backward costs more than forward
    monkeypatch.setattr(bench, "TRAIN_CROP_HW", (32, 48))
    monkeypatch.setattr(bench, "TRAIN_BATCH", 2)
    train = bench._train_rows(1, {"srgb": 1.5, "raw": 0.5})
    assert len(train) == 8 and {r["precision"] for r in train} == {"fp32", "bf16"}
    for r in train:
        assert r["view_ms_per_image"] == (0.5 if r["what"].endswith("raw") else 1.5)
        assert r["train_ms_per_image"] == pytest.approx(r["step_ms_per_image"] + r["view_ms_per_image"])
