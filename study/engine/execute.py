"""Execution: where a plan's tasks run. Dask runs them; this module only chooses the scheduler.

  auto         (default) a distributed.LocalCluster of one worker process per core (at most 4),
               the cores shared out as Dr.Jit threads, for a plan of AUTO_MIN_TASKS tasks or more
               (not counting references whose file is there: cache hits);
               a smaller plan (an A/B of one edited technique, a re-judged table) in-process, as
               starting the workers would cost more than it saves.
  in-process   Dask's synchronous scheduler in this process (`--workers 1`: one process, for
               debugging).
  local        a LocalCluster of N worker processes, one Dask thread each (Dr.Jit's JIT state and
               the EGL context are per process; a worker's parallelism is Dr.Jit's own thread pool,
               `threads`, by default the cores shared out: two workers of two threads on two cores
               took 565 s where two of one took 352 s).
  scheduler    an existing Dask scheduler (tcp://HOST:PORT); every worker must see the cache
               folder at the same path (a shared filesystem) and have this project installed.
Tasks return small dicts; their images go through the cache. A task lost with its worker is run
again elsewhere by the scheduler; a task that raises stops the study with its message.

A session may have a deadline (`run --stop-after`, wall-clock seconds since the epoch, as every
worker of a cluster reads the same clock): a task that would start after it, or whose inputs were
not made, returns STOPPED at once instead of running, so the tasks in flight finish (each is the
cache's unit: a task cut short would be lost) and the rest of the graph drains in moments.
"""
from __future__ import annotations

import asyncio
import os
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm


AUTO_MIN_TASKS = 8
AUTO_MAX_WORKERS = 4
CLOSE_TIMEOUT_S = 60          # a LocalCluster's close (its default, 30 s, ran out under load)


def cores() -> int:
    """The cores this process may use (its affinity, not the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Executor:
    kind: str = "in-process"       # auto | in-process | local | scheduler
    workers: int = 1
    threads: int | None = None     # Dr.Jit threads per worker process (None: the cores shared out)
    address: str | None = None

    @classmethod
    def auto(cls, threads: int | None = None) -> "Executor":
        n = cores()
        if n < 2:
            return cls("in-process", threads=threads)
        return cls("auto", workers=min(n, AUTO_MAX_WORKERS), threads=threads)

    def worker_threads(self) -> int | None:
        """Dr.Jit threads of each cluster worker: the user's, else this machine's cores shared out."""
        if self.threads or self.kind == "scheduler":
            return self.threads
        return max(1, cores() // max(1, self.workers))

    def describe(self) -> str:
        if self.kind in ("local", "auto"):
            d = f"LocalCluster, {self.workers} worker processes x {self.worker_threads()} threads"
            return d if self.kind == "local" else f"auto: {d} (plans under {AUTO_MIN_TASKS} tasks in-process)"
        if self.kind == "scheduler":
            return f"Dask scheduler {self.address}"
        return "in-process"


@dataclass(frozen=True)
class Call:
    """A task's spec (study.engine.specs), opaque to Dask (so a field that happens to equal a key,
    such as the task's own key, is not taken for a dependency)."""
    spec: object

    def __call__(self, deps):
        return self.spec()


# What a task returns in place of its result when the session's deadline had passed as it would start.
STOPPED = "taa-study: not started, past the deadline"


def now() -> float:
    """The clock deadlines are read on (wall seconds since the epoch: the same on every worker)."""
    return time.time()


def _run(call: Call, deps, deadline=None):
    """The task's result and its wall seconds (where the study's time goes, by task kind); (STOPPED,
    0) without running it when `deadline` has passed or a task it depends on was not run."""
    if deadline is not None and (now() >= deadline or any(isinstance(d, tuple) and d and d[0] == STOPPED
                                                            for d in deps)):
        return STOPPED, 0.0
    t0 = time.perf_counter()
    out = call(deps)
    return out, time.perf_counter() - t0


def graph(plan, deadline: float | None = None) -> dict:
    """The Dask graph of a plan: key -> (run, Call, [dependency keys], deadline); dependencies only
    order the tasks (their results are small records; the data they made is read from the cache)."""
    return {key: (_run, Call(t.spec), list(t.deps), deadline) for key, t in plan.tasks.items()}


class _Bar:
    def __init__(self, plan, progress: bool):
        self.kinds = Counter(t.kind for t in plan.tasks.values())
        self.done = Counter()
        self.seconds = Counter()      # task seconds by kind (summed over workers)
        self.by_scene = Counter()     # (scene, kind) -> task seconds: where a study's time goes
        self.scene_of = {k: Path(t.spec.scene).stem for k, t in plan.tasks.items() if getattr(t.spec, "scene", None)}
        self.bar = tqdm(total=len(plan.tasks), desc="study", unit="task", disable=not progress or not plan.tasks,
                        file=sys.stderr, mininterval=0.5)

    def finished(self, kind: str, seconds: float = 0.0, key=None):
        self.done[kind] += 1
        self.seconds[kind] += seconds
        if key in self.scene_of:
            self.by_scene[self.scene_of[key], kind] += seconds
        self.bar.set_postfix_str(", ".join(f"{k} {self.done[k]}/{n}" for k, n in sorted(self.kinds.items())),
                                 refresh=False)
        self.bar.update(1)

    def close(self):
        self.bar.close()


class Session:
    """Where a study's plans run, held open across its precision rounds: a cluster started once,
    not once per round (its workers keep their compiled kernels and their EGL contexts)."""

    def __init__(self, executor: Executor = Executor(), log=print, deadline: float | None = None):
        self.executor, self.log = executor, log
        self._client = self._cluster = None
        self.task_seconds = Counter()     # kind -> task seconds over every round so far
        self.scene_seconds = Counter()    # (scene, kind) -> task seconds over every round so far
        self.deadline = deadline          # no task starts after it (now()); None: none
        self.not_started = Counter()      # kind -> tasks of the last execute() left for the deadline

    def seconds_by_scene(self) -> dict:
        """scene -> task kind -> task seconds over every round so far (a scene file's by its stem)."""
        out: dict = {}
        for (name, kind), sec in sorted(self.scene_seconds.items()):
            out.setdefault(name, {})[kind] = round(sec, 2)
        return out

    def past_deadline(self) -> bool:
        """Whether the session's deadline has passed (no new task would start)."""
        return self.deadline is not None and now() >= self.deadline

    def _connect(self, n_tasks: int):
        ex = self.executor
        if self._client is not None or ex.kind == "in-process" or (ex.kind == "auto" and n_tasks < AUTO_MIN_TASKS):
            return self._client
        import dask
        from distributed import Client, LocalCluster
        # the workers' statistical profiler samples every thread's stack every 10 ms: CPU taken from the tasks
        dask.config.set({"distributed.worker.profile.enabled": False})
        # The nanny's default MALLOC_TRIM_THRESHOLD_=65536 hands every freed frame buffer back to the
        # kernel and faults it in again on the next: 127 s of system time in a 205-s study on two
        # workers (12 s in-process). glibc's own dynamic threshold instead; BLAS threads as Dr.Jit's.
        n = str(self.executor.worker_threads() or 1)
        dask.config.set({"distributed.nanny.pre-spawn-environ": {
            "OMP_NUM_THREADS": n, "MKL_NUM_THREADS": n, "OPENBLAS_NUM_THREADS": n}})
        if self.executor.kind in ("local", "auto"):
            import logging
            # A task's own error is reported once, by the study, not again by the worker's log.
            self._cluster = LocalCluster(n_workers=self.executor.workers, threads_per_worker=1, processes=True,
                                         dashboard_address=":0", silence_logs=logging.CRITICAL)
            self._client = Client(self._cluster)
            from study.engine.worker_setup import DrJitThreads
            self._client.register_plugin(DrJitThreads(self.executor.worker_threads()), name="taa-drjit-threads")
        else:
            self._client = Client(self.executor.address)
        if self._client.dashboard_link:
            self.log(f"Dask dashboard: {self._client.dashboard_link}")
        return self._client

    def close(self):
        """Close the client and the cluster. A cluster slow to stop (a loaded machine: the nanny's
        close timed out once under load 10 on 2 cores) costs no finished result: said, and its
        worker processes end with this one."""
        for what, obj in (("client", self._client), ("cluster", self._cluster)):
            if obj is None:
                continue
            try:
                obj.close(timeout=CLOSE_TIMEOUT_S) if what == "cluster" else obj.close()
            except (Exception, asyncio.CancelledError) as exc:      # TimeoutError, a comm already gone
                self.log(f"Dask: the {what} did not close cleanly ({type(exc).__name__}); its worker "
                         "processes end with this one")
        self._client = self._cluster = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def execute(self, plan, progress: bool = True) -> dict:
        """Run every task of the plan; key -> result (the plan's cached results included). Under a
        deadline the tasks it left unstarted have no result: `not_started` counts them by kind."""
        results = dict(plan.cached)
        self.not_started = Counter()
        if not plan.tasks:
            return results
        dsk = graph(plan, self.deadline)
        keys = list(dsk)
        bar = _Bar(plan, progress)
        try:
            client = self._connect(sum(not getattr(t, "likely_cached", False) for t in plan.tasks.values()))
            if client is None:
                import dask
                from dask.callbacks import Callback

                class _Progress(Callback):
                    def _posttask(self, key, result, dsk_, state, worker_id):
                        if not _stopped(result[0]):
                            bar.finished(plan.tasks[key].kind, result[1], key)

                with _Progress():
                    out = dask.get(dsk, keys)
                results.update((k, r) for k, (r, _) in zip(keys, out) if not _stopped(r))
            else:
                from distributed import as_completed
                from distributed.scheduler import KilledWorker
                futures = client.get(dsk, keys, sync=False)
                for fut in as_completed(futures):
                    try:
                        r, seconds = fut.result()     # re-raises a task's own exception
                    except KilledWorker:
                        raise _killed(plan.tasks[fut.key], None if self.executor.kind == "scheduler"
                                      else self.executor.workers) from None
                    if not _stopped(r):
                        results[fut.key] = r
                        bar.finished(plan.tasks[fut.key].kind, seconds, fut.key)
                missing = [k for k in keys if k not in results and not self.deadline]
                if missing:
                    raise RuntimeError(f"{len(missing)} tasks returned no result")
        finally:
            bar.close()
        self.task_seconds.update(bar.seconds)
        self.scene_seconds.update(bar.by_scene)
        self.not_started = Counter(plan.tasks[k].kind for k in keys if k not in results)
        return results


def _killed(task, workers: int | None):
    """The error of a task whose worker process died each time it ran it (Dask's KilledWorker, after
    its `allowed-failures` retries): the task's kind and scene, and the likely cause. `workers`: a
    LocalCluster's (each may use its share of this machine's memory), None for a scheduler's."""
    import psutil

    from study.engine.tasks import TaskError
    spec = task.spec
    where = f" of scene {getattr(spec, 'scene', '?')} at {spec.width}x{spec.height}" if hasattr(spec, "width") else ""
    share = "" if workers is None else (f" ({psutil.virtual_memory().total / max(workers, 1) / 2 ** 30:.1f} GB, "
                                        f"this machine's memory shared by {workers} workers)")
    fewer = "Fewer --workers gives each more memory; " if workers is not None else ""
    return TaskError(f"a {task.kind} task{where} ended its worker process each time it ran (Dask's KilledWorker): "
                     f"most often memory past the worker's limit{share}, or a crash in native code. {fewer}"
                     f"`taa-study estimate` prints what the study's largest process needs")


def _stopped(result) -> bool:
    return isinstance(result, str) and result == STOPPED

