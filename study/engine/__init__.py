"""The study engine: plan (what to compute, content-keyed) -> tasks (pure functions) -> execute
(in-process or Dask) -> store (tamper-evident artefacts in the cache); results gathers what the
reporting reads. Modules: plan, tasks, run_task, judge, agreement, drive, execute, store, runner,
results, costs, estimate."""
