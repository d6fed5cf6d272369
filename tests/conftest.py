"""Fixtures shared by the test folders, and each pytest-xdist worker's thread budget."""
import os

import pytest


def pytest_configure(config):
    """Under pytest-xdist (-n N) every worker gets cores // N threads in OpenMP/BLAS, torch and
    Dr.Jit (children inherit it), so N workers never oversubscribe the machine's cores."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT", "")
    if os.environ.get("PYTEST_XDIST_WORKER") and workers.isdigit():
        from workbench.compute.local import apply_thread_budget
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        apply_thread_budget(max(1, cores // int(workers)))


@pytest.fixture(scope="session")
def mi():
    """Mitsuba with the llvm_ad_spectral variant (LLVM 19 located by select_variant)."""
    from workbench.render.variants import import_mitsuba
    try:
        return import_mitsuba("llvm_ad_spectral")
    except (ImportError, AttributeError, ValueError, RuntimeError) as exc:
        pytest.skip(f"llvm_ad_spectral unavailable: {exc}")
