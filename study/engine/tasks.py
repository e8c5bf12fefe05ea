"""The contract of the study's tasks: pure functions of their arguments (specs and keys, all
small and picklable), run in-process or on a Dask worker. Each writes its artefact atomically into the cache, under its
key and a per-key lock, and returns only keys and small numbers; images never travel through the
scheduler. A task whose artefact is already complete (another study made it meanwhile) reads it.
The tasks live apart (reference_task, run_task, judge, agreement), so each kind's key names only
its own code (study.engine.plan.CODE).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import backend  # noqa: F401  (libLLVM and the Mitsuba variant, in every worker process)


class TaskError(RuntimeError):
    """A task that fails deterministically (bad input): the study stops with this message."""


def _deterministic(fn):
    """Errors that running again cannot fix (a bad scene, NaN in a buffer, bad technique parameters)
    become a TaskError naming the task, so every executor stops the study with the same message."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from raster.visibility import RasterError
        from references.result import ReferenceError
        from scenes import SceneError
        try:
            return fn(*args, **kwargs)
        except TaskError:
            raise
        except (SceneError, RasterError, ReferenceError, ValueError, KeyError, TypeError) as exc:
            what = fn.__name__.removesuffix("_task")
            where = getattr(args[0], "name", None) or args[1]
            raise TaskError(f"{what} of {where!r}: {type(exc).__name__}: {exc}") from None
    return wrapper


@dataclass(frozen=True)
class Context:
    cache_root: str
    threads: int | None = None       # Dr.Jit threads in this process (None: its default)


_configured: set = set()


def _setup(ctx: Context):
    if ctx.threads and ctx.threads not in _configured:
        from backend import dr
        dr.set_thread_count(int(ctx.threads))
        _configured.add(ctx.threads)
    from study.engine.store import Store
    return Store(Path(ctx.cache_root))


def display_of(cache, scene, t: int, w: int, h: int, display_settings: dict):
    """Frame t's display transform (display/__init__.py): from its reference at `display_settings`,
    the probe bound (study.config.precision), whatever the precision of the references it is
    judged against. Its white point is the brightest pixel, a noisy extreme: on frame 0 of
    hairball_rotating_lit at 1600x900 it was 1.0344 at 2 LSB and 1.0352 at 8, either side of
    1.03 / 1.04 to 3 digits, and every figure moved with it. One reference per frame gives one
    transform at every precision and under either rule; a probe is ~6 % of a 0.5-LSB reference's
    samples. Read from the reference's display record (references.cache): the probe itself may be
    gone once the study refined past it (study.engine.supersede)."""
    return display_reference(cache, scene, t, w, h, display_settings)[1]


def display_reference(cache, scene, t: int, w: int, h: int, display_settings: dict):
    """(key, display transform) of the reference frame t's display transform comes from (display_of)."""
    return cache.display(scene, t, w, h, **display_settings)


@lru_cache(maxsize=64)
def load_scene(spec: str):
    from scenes import get_scene
    return get_scene(spec)
