"""The benchmarks' timing helper measures what it says: wall time includes waiting, CPU time
does not, and a CPU-bound call costs CPU time close to its wall time."""
import time

import pytest

from workbench.bench import all_benches
from workbench.bench.timing import best_wall_ms, median_times_ms, timed


def _spin(seconds: float) -> None:
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_wall_time_counts_sleep_and_cpu_time_does_not():
    out, t = timed(lambda: time.sleep(0.05) or "done")
    assert out == "done"
    assert 50.0 <= t.wall_ms < 1000.0
    assert t.cpu_ms < 10.0


def test_cpu_bound_call_costs_its_cpu_time():
    wall, cpu = median_times_ms(lambda: _spin(0.02), 3)
    assert cpu == pytest.approx(20.0, abs=5.0)
    assert wall >= cpu * 0.95           # one thread: CPU time cannot exceed wall time


def test_best_wall_ms_ranks_calls_and_warms_each_once():
    calls = {"short": 0, "long": 0}

    def make(name, s):
        def fn():
            calls[name] += 1
            time.sleep(s)
        return fn
    best = best_wall_ms({"short": make("short", 0.005), "long": make("long", 0.03)}, repeats=2)
    assert calls == {"short": 3, "long": 3}
    assert 5.0 <= best["short"] < best["long"] and best["long"] >= 30.0


def test_every_benchmark_lives_in_the_bench_package():
    benches = all_benches()
    assert {"pipeline", "render", "optics", "isp", "sensor", "city", "lens-camera"} <= set(benches.names)
    assert all(fn.__module__.startswith("workbench.bench.") for fn in benches.values())
