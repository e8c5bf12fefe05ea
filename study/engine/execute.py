"""Execution: where a plan's tasks run. Dask runs them; this module only chooses the scheduler.

  in-process   (default) Dask's synchronous scheduler in this process: no extra processes.
  local        a distributed.LocalCluster of N worker processes, one Dask thread each (Dr.Jit's
               JIT state and the EGL context are per process; a worker's parallelism is Dr.Jit's
               own thread pool, `threads`).
  scheduler    an existing Dask scheduler (tcp://HOST:PORT); every worker must see the cache
               folder at the same path (a shared filesystem) and have this project installed.
Tasks return small dicts; their images go through the cache. A task lost with its worker is run
again elsewhere by the scheduler; a task that raises stops the study with its message.
"""
from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass

from tqdm import tqdm


@dataclass(frozen=True)
class Executor:
    kind: str = "in-process"       # in-process | local | scheduler
    workers: int = 1
    threads: int | None = None     # Dr.Jit threads per worker process
    address: str | None = None

    def describe(self) -> str:
        if self.kind == "local":
            return f"LocalCluster, {self.workers} worker processes" + (f" x {self.threads} threads" if self.threads else "")
        if self.kind == "scheduler":
            return f"Dask scheduler {self.address}"
        return "in-process"


@dataclass(frozen=True)
class Call:
    """A task's function and arguments, opaque to Dask (so an argument that happens to equal a key,
    such as the task's own key, is not taken for a dependency)."""
    fn: object
    args: tuple

    def __call__(self, deps):
        return self.fn(*self.args)


def _run(call: Call, deps):
    return call(deps)


def graph(plan) -> dict:
    """The Dask graph of a plan: key -> (run, Call, [dependency keys]); dependencies only order the
    tasks (their results are small records; the data they made is read from the cache)."""
    return {key: (_run, Call(t.fn, t.args), list(t.deps)) for key, t in plan.tasks.items()}


class _Bar:
    def __init__(self, plan, progress: bool):
        self.kinds = Counter(t.kind for t in plan.tasks.values())
        self.done = Counter()
        self.bar = tqdm(total=len(plan.tasks), desc="study", unit="task", disable=not progress or not plan.tasks,
                        file=sys.stderr, mininterval=0.5)

    def finished(self, kind: str):
        self.done[kind] += 1
        self.bar.set_postfix_str(", ".join(f"{k} {self.done[k]}/{n}" for k, n in sorted(self.kinds.items())),
                                 refresh=False)
        self.bar.update(1)

    def close(self):
        self.bar.close()


def execute(plan, executor: Executor = Executor(), progress: bool = True, log=print) -> dict:
    """Run every task of the plan; key -> result (the plan's cached results included)."""
    results = dict(plan.cached)
    if not plan.tasks:
        return results
    dsk = graph(plan)
    keys = list(dsk)
    bar = _Bar(plan, progress)
    try:
        if executor.kind == "in-process":
            import dask
            from dask.callbacks import Callback

            class _Progress(Callback):
                def _posttask(self, key, result, dsk_, state, worker_id):
                    bar.finished(plan.tasks[key].kind)

            with _Progress():
                out = dask.get(dsk, keys)
            results.update(zip(keys, out))
        else:
            from distributed import Client, LocalCluster, as_completed
            if executor.kind == "local":
                import logging
                # A task's own error is reported once, by the study, not again by the worker's log.
                cluster = LocalCluster(n_workers=executor.workers, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.CRITICAL)
                client = Client(cluster)
            else:
                cluster, client = None, Client(executor.address)
            try:
                if client.dashboard_link:
                    log(f"Dask dashboard: {client.dashboard_link}")
                futures = client.get(dsk, keys, sync=False)
                by_key = dict(zip(keys, futures))
                for fut in as_completed(futures):
                    results[fut.key] = fut.result()     # re-raises a task's own exception
                    bar.finished(plan.tasks[fut.key].kind)
                missing = [k for k in by_key if k not in results]
                if missing:
                    raise RuntimeError(f"{len(missing)} tasks returned no result")
            finally:
                client.close()
                if cluster is not None:
                    cluster.close()
    finally:
        bar.close()
    return results
