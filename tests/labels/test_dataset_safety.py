"""Data-set safety: clear one-line errors for a bad output folder or spec, lazy planning with a frame
limit, no index file claiming a frame that is not on disk, one run per folder, and worker processes
that die with the run that started them."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from labels_helpers import tiny_renderer

from workbench.cli import main
from workbench.errors import InputFileError, OutputPathError, ParameterError
from workbench.jobs import run_job
from workbench.project import Project, save_project
from workbench.datasets.dataset import MAX_FRAMES, frame_path, run_dataset


def start(project, frames, out, **kw):
    """A data-set job advanced to its first progress step (so it holds the folder)."""
    job = run_dataset(project, frames, out, workers=0, renderer=tiny_renderer, **kw)
    first = next(job)
    return job, first


def test_out_that_is_a_file_and_a_spec_that_is_not_an_object_give_one_line_errors(tmp_path, capsys):
    save_project(Project(seed=1, scene={"kind": "city"}), tmp_path / "p.json")
    (tmp_path / "file").write_text("x")
    assert main(["dataset", str(tmp_path / "p.json"), "--frames", "1", "--out", str(tmp_path / "file")]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "file" in err and "not a folder" in err and "Traceback" not in err
    for n, doc in enumerate(("[1, 2]", "3", '"spec"', "{broken")):
        out = tmp_path / f"set{n}"
        (out / "frames").mkdir(parents=True)
        (out / "dataset_spec.json").write_text(doc)
        with pytest.raises(InputFileError, match="dataset_spec.json") as info:
            run_job(run_dataset(Project(seed=1), 1, out, workers=0, renderer=tiny_renderer))
        assert doc not in info.value.problem                # names the file, never echoes it


def test_huge_frame_counts_are_refused_or_planned_lazily(tmp_path, capsys):
    save_project(Project(seed=1), tmp_path / "p.json")
    t0 = time.monotonic()
    assert main(["dataset", str(tmp_path / "p.json"), "--frames", "100000000", "--out",
                 str(tmp_path / "big")]) == 2
    assert f"{MAX_FRAMES:,}" in capsys.readouterr().err and time.monotonic() - t0 < 10
    with pytest.raises(ParameterError, match="frames"):
        next(run_dataset(Project(), True, tmp_path / "b", renderer=tiny_renderer))
    # The largest allowed set starts rendering at once: nothing is planned frame by frame up front.
    job = run_dataset(Project(seed=1), MAX_FRAMES, tmp_path / "max", workers=0, renderer=tiny_renderer)
    t0 = time.monotonic()
    assert next(job).message.startswith("frame 0")
    assert time.monotonic() - t0 < 20
    job.close()


def test_a_frame_replaced_by_a_directory_is_never_claimed(tmp_path):
    out = tmp_path / "d"
    run_job(run_dataset(Project(seed=2), 2, out, workers=0, renderer=tiny_renderer))
    assert (out / "manifest.json").exists()
    frame_path(out, 1).unlink()
    frame_path(out, 1).mkdir()
    with pytest.raises(OutputPathError, match="frame_000001.npz.*not a regular file"):
        run_job(run_dataset(Project(seed=2), 2, out, workers=0, renderer=tiny_renderer))
    assert not (out / "manifest.json").exists() and not (out / "coco.json").exists()
    frame_path(out, 1).rmdir()
    done = run_job(run_dataset(Project(seed=2), 2, out, workers=0, renderer=tiny_renderer))
    assert done.rendered == [1] and len(json.loads((out / "manifest.json").read_text())["frames"]) == 2


def test_a_second_run_on_the_same_folder_is_refused_naming_the_first(tmp_path):
    out = tmp_path / "d"
    first, _ = start(Project(seed=3), 3, out)
    with pytest.raises(OutputPathError, match=rf"in use by workbench dataset \(pid {os.getpid()} "):
        run_job(run_dataset(Project(seed=3), 3, out, workers=0, renderer=tiny_renderer))
    result = run_job(first)                               # the first run is untouched and finishes
    assert sorted(result.rendered) == [0, 1, 2]
    again = run_job(run_dataset(Project(seed=3), 3, out, workers=0, renderer=tiny_renderer))
    assert again.reused == [0, 1, 2]                      # the lock went with the first run


def _children(pid):
    psutil = pytest.importorskip("psutil")
    return psutil.Process(pid).children(recursive=True)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_pool_workers_die_with_the_run(tmp_path, sig):
    psutil = pytest.importorskip("psutil")
    helpers = Path(__file__).resolve().parents[1] / "compute"
    script = (f"import sys; sys.path.insert(0, {str(helpers)!r})\n"
              "from compute_helpers import slow_renderer\n"
              "from workbench.project import Project\n"
              "from workbench.datasets.dataset import run_dataset\n"
              f"for p in run_dataset(Project(seed=5), 6, {str(tmp_path / 'k')!r}, workers=2,\n"
              "                      renderer=slow_renderer):\n"
              "    print(p.message, flush=True)\n")
    env = {**os.environ, "WB_TEST_SLEEP_S": "60"}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.DEVNULL)
    workers = []
    deadline = time.monotonic() + 60
    while len(workers) < 2 and time.monotonic() < deadline:
        time.sleep(0.5)
        workers = [c for c in _children(proc.pid) if "multiprocessing" in " ".join(c.cmdline())]
    assert len(workers) >= 2, "the pool did not start"
    time.sleep(3)                                         # the workers are inside their frames now
    proc.send_signal(sig)
    proc.wait(timeout=30)
    gone, alive = psutil.wait_procs(workers, timeout=15)
    for p in alive:
        p.kill()
    assert not alive, f"workers outlived the run: {[p.pid for p in alive]}"
    assert not list((tmp_path / "k" / "frames").glob("frame_*.npz"))
