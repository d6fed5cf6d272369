"""Where work runs. local.run_jobs(fn, jobs, workers, cancel): in-process or a spawned process pool;
a cluster backend (Ray) is to offer the same generator over the same picklable jobs."""
