"""compute.run_jobs on this machine: the spec is checked, and each worker gets its thread budget."""
import math

import pytest
from compute_helpers import thread_budget

from workbench.compute import ComputeSpec, run_jobs
from workbench.errors import ParameterError


def test_every_worker_gets_its_thread_budget():
    (_, budget), = run_jobs(thread_budget, [0], ComputeSpec(workers=1, cpus_per_task=1))
    assert budget == (1, "1", 1)


def test_local_spec_runs_jobs_and_bad_specs_name_the_field():
    assert dict(run_jobs(math.factorial, [3, 4], ComputeSpec(workers=0))) == {3: 6, 4: 24}
    for kwargs, field in (({"backend": "slurm"}, "backend"), ({"workers": -1}, "workers"),
                          ({"address": "auto"}, "address"), ({"cpus_per_task": float("nan")}, "cpus_per_task"),
                          ({"backend": "ray", "gpus_per_task": -1}, "gpus_per_task"),
                          ({"backend": "ray", "address": "nowhere"}, "address"),
                          ({"max_retries": 1000}, "max_retries"), ({"workers": True}, "workers")):
        with pytest.raises(ParameterError, match=field):
            ComputeSpec(**kwargs)
    assert ComputeSpec(backend="ray").task_cpus == 1.0 and ComputeSpec(workers=1).task_cpus >= 1
