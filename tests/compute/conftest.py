"""A real local Ray cluster (2 CPUs, small object store, no dashboard) for the compute tests."""
import os
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="session")
def markers(tmp_path_factory):
    """Folder for attempt markers, named in the environment that workers inherit."""
    folder = tmp_path_factory.mktemp("markers")
    os.environ["WB_TEST_MARKERS"] = str(folder)
    return folder


@pytest.fixture(scope="module")
def ray_cluster(markers):
    """ray, initialised with a 2-CPU local cluster whose workers can import the test helpers.

    Module scope: the cluster is shut down before the rest of the suite runs. A driver left
    connected aborts the whole pytest process (SIGABRT from Ray's core worker) when its raylet
    misses heartbeats on a loaded machine, which once killed CI in an unrelated GUI test."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'camera-workbench[cluster]')")
    paths = [str(HERE), str(HERE.parent / "labels"), str(HERE.parents[1])]
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(paths + ([old] if old else []))
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=80 * 2 ** 20,
             log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()
