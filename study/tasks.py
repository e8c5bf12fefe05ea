"""The study's tasks: pure functions of their arguments (specs and keys, all small and picklable),
run in-process or on a Dask worker. Each writes its artefact atomically into the cache, under its
key and a per-key lock, and returns only keys and small numbers; images never travel through the
scheduler. A task whose artefact is already complete (another study made it meanwhile) reads it.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import backend  # noqa: F401  (libLLVM and the Mitsuba variant, in every worker process)

from provenance import task_key


class TaskError(RuntimeError):
    """A task that fails deterministically (bad input): the study stops with this message."""


def _deterministic(fn):
    """Errors that running again cannot fix (a bad scene, NaN in a buffer, bad technique parameters)
    become a TaskError naming the task, so every executor stops the study with the same message."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from raster.visibility import RasterError
        from references.render import ReferenceError
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
    from .store import Store
    return Store(Path(ctx.cache_root))


@lru_cache(maxsize=64)
def load_scene(spec: str):
    from scenes import get_scene
    return get_scene(spec)


# -- reference -----------------------------------------------------------------------------------
@_deterministic
def reference_task(ctx: Context, scene_spec: str, t: int, w: int, h: int, settings: dict) -> dict:
    from references import ReferenceCache
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with store.lock(task_key("reference-lock", (scene.content_hash, t, w, h, settings))):
        ref, cached = ReferenceCache(Path(ctx.cache_root)).get(scene, t, w, h, **settings)
    return {"kind": "reference", "key": ref.key, "t": t, "rendered": not cached, "spp": ref.spp,
            "seconds": ref.seconds, "noise_psnr_db": ref.noise_psnr_db}


# -- a technique run -------------------------------------------------------------------------------
@_deterministic
def run_task(ctx: Context, scene_spec: str, w: int, h: int, protocol, configs: list, keys: dict,
             folders: dict, ref_settings: dict, deps=()) -> dict:
    """Run the techniques `configs` (sharing raster frames) over `protocol` on one scene; file each
    technique's judged frames under its key. Returns label -> done record summary."""
    from display import DisplayTransform

    from .protocols import run_schedule
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    out, todo = {}, []
    lock = task_key("run-lock", sorted(keys.values()))
    with store.lock(lock):
        for c in configs:
            rec = store.done(Path(folders[c.label]), keys[c.label], whole=True)
            if rec is not None:
                out[c.label] = _run_summary(rec, computed=False)
            else:
                todo.append(c)
        if todo:
            schedule = protocol.schedule(scene)
            displays = {}
            if any(c.make().inputs.display for c in todo):
                from references import ReferenceCache
                cache = ReferenceCache(Path(ctx.cache_root))
                for t in sorted({s.t for s in schedule if s.keep}):   # one reference held at a time
                    displays[t] = DisplayTransform.from_reference(cache.get(scene, t, w, h, **ref_settings)[0].image)
            writers = {c.label: store.writer(Path(folders[c.label])) for c in todo}
            frames: dict = {c.label: [] for c in todo}

            def emit(label, f, img):      # each judged frame goes to the cache as it is made
                if not _finite(img):
                    raise TaskError(f"scene {scene.name!r}, {protocol.name}: technique {label!r} produced "
                                    f"NaN/Inf in frame(s) {[f]}")
                writers[label].add(f"frame_{f:04d}.exr", img)
                frames[label].append(f)
            fresh = run_schedule(scene, w, h, schedule, todo, displays,
                                 desc=f"{scene.name}: {protocol.name} ({', '.join(c.label for c in todo)})",
                                 progress=False, emit=emit)
            for c in todo:
                r = fresh[c.label]
                meta = {"label": c.label, "technique": c.name, "overrides": [list(o) for o in c.overrides],
                        "output_space": r["output_space"], "nonfinite_inputs": r["nonfinite"],
                        "frames": sorted(frames[c.label]), "stats": {str(f): v for f, v in r["stats"].items()}}
                rec = writers[c.label].seal(keys[c.label], meta)
                out[c.label] = _run_summary(rec, computed=True)
    return {"kind": "run", "runs": out}


def _finite(img) -> bool:
    import numpy as np
    return bool(np.all(np.isfinite(img)))


def _run_summary(rec: dict, computed: bool) -> dict:
    return {"key": rec["key"], "frames": rec["frames"], "output_space": rec["output_space"],
            "stats": rec.get("stats", {}), "computed": computed}


# -- agreement of a scene -------------------------------------------------------------------------------
@_deterministic
def agreement_task(ctx: Context, scene_spec: str, w: int, h: int, samples: int, ref_settings: dict,
                   key: str, path: str, deps=()) -> dict:
    from references import ReferenceCache

    from .agreement import check_agreement
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with store.lock(key):
        data = store.load_record(Path(path), key)
        if data is None:
            a = check_agreement(scene, w, h, samples=samples, cache=ReferenceCache(Path(ctx.cache_root)),
                                progress=False, **_agreement_settings(ref_settings))
            data = store.save_record(Path(path), key, a.as_dict())
            computed = True
        else:
            computed = False
    return {"kind": "agreement", "key": key, "data": data, "computed": computed}


def _agreement_settings(ref_settings: dict) -> dict:
    return dict(ref_settings)

