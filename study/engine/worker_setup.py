"""What a cluster worker sets up before its first task (its own module: distributed is imported
only when a cluster is used)."""
from distributed import WorkerPlugin


class DrJitThreads(WorkerPlugin):
    """Each worker's Dr.Jit thread pool, set before its first task and in a worker the nanny
    restarts: the machine's cores shared out, not each worker taking them all."""

    def __init__(self, n: int | None):
        self.n = n

    def setup(self, worker):
        if self.n:
            import drjit as dr
            dr.set_thread_count(int(self.n))
