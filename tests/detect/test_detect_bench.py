"""`workbench bench detect` is registered and its rows carry positive per-image times (tiny sizes)."""
from workbench.bench import all_benches
from workbench.bench.detect import _network_rows, _view_rows


def test_detect_bench_rows():
    assert "detect" in all_benches().names
    views = _view_rows(48, 64, 1)
    assert [r["what"] for r in views] == ["raw", "linear", "srgb"]
    assert views[0]["isp_ms"] == 0.0 and all(r["total_ms_per_image"] > 0 for r in views)
    nets = _network_rows(32, 48, 1, "cpu")
    assert {r["what"] for r in nets} == {"mobile srgb", "mobile raw", "resnet18 srgb", "resnet18 raw"}
    assert all(r["train_ms_per_image"] > 0 and r["infer_ms_per_image"] > 0 for r in nets)
