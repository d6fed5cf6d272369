"""Frame renderers for the compute tests (module-level, so spawned and Ray workers import them).

Attempts are counted with marker files in the folder named by $WB_TEST_MARKERS, which the tests
set before workers start."""
import os
import signal
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "labels"))

from labels_helpers import tiny_renderer  # noqa: E402

from workbench.errors import ParameterError  # noqa: E402

MARKERS_ENV = "WB_TEST_MARKERS"


def count_attempt(tag: str) -> int:
    """Record one attempt of `tag`; return how many were recorded before this one."""
    folder = Path(os.environ[MARKERS_ENV])
    before = len(list(folder.glob(f"{tag}.*")))
    (folder / f"{tag}.{os.getpid()}.{time.monotonic_ns()}").touch()
    return before


def crash_once_renderer(project, seeds):
    """tiny_renderer, except that the first attempt at frame 1 kills its own worker (SIGKILL) half-way."""
    if seeds.index == 1 and count_attempt(f"crash-{project.seed}-1") == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return tiny_renderer(project, seeds)


def bad_project_renderer(project, seeds):
    """Refuses every project (a deterministic error), counting attempts."""
    count_attempt(f"bad-{project.seed}-{seeds.index}")
    raise ParameterError("render.band_count", project.render.band_count, "≤ 0 in this test (always refused)")


def slow_renderer(project, seeds):
    """tiny_renderer after a pause, so a run can be killed while frames are in flight."""
    time.sleep(float(os.environ.get("WB_TEST_SLEEP_S", "1")))
    return tiny_renderer(project, seeds)


def thread_budget(_job):
    """(Dr.Jit threads after the variant is chosen, OMP_NUM_THREADS, torch threads a training run
    would use) as a worker sees them."""
    from workbench.detect.devices import choose_threads
    from workbench.render.variants import select_variant
    select_variant("llvm_ad_spectral")
    import drjit as dr
    return dr.thread_count(), os.environ.get("OMP_NUM_THREADS"), choose_threads(None)


def progress_renderer(project, seeds, on_progress=None):
    """tiny_renderer that reports part-way progress (1/4, 2/4, then 3/4 again every 0.2 s) until
    the test has seen a part-way report (it creates the file named by project.description) or
    60 s pass: a loaded machine may start Ray's progress actor late, and the actor keeps only
    the latest report of a task, so fixed sleeps could hide every part-way report."""
    from workbench.jobs import Progress
    seen_flag = Path(project.description) if project.description else None
    deadline = time.monotonic() + 60.0
    step = 0
    while True:
        step = min(step + 1, 3)
        on_progress(Progress(step, 4))
        time.sleep(0.2)
        if seen_flag is None or seen_flag.exists() or time.monotonic() > deadline:
            break
    on_progress(Progress(4, 4))
    return tiny_renderer(project, seeds)


def die(_job):
    """A job whose worker always dies (SIGKILL)."""
    os.kill(os.getpid(), signal.SIGKILL)


def sigint_ignored(_job) -> bool:
    """Whether this (worker) process ignores SIGINT."""
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN
