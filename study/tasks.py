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


def _references(ctx: Context, scene, ts, w, h, settings: dict) -> dict:
    from references import ReferenceCache
    cache = ReferenceCache(Path(ctx.cache_root))
    return {t: cache.get(scene, t, w, h, **settings)[0] for t in ts}


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
            rec = store.done(Path(folders[c.label]), keys[c.label])
            if rec is not None:
                out[c.label] = _run_summary(rec, computed=False)
            else:
                todo.append(c)
        if todo:
            schedule = protocol.schedule(scene)
            displays = {}
            if any(c.make().inputs.display for c in todo):
                kept_t = sorted({s.t for s in schedule if s.keep})
                refs = _references(ctx, scene, kept_t, w, h, ref_settings)
                displays = {t: DisplayTransform.from_reference(r.image) for t, r in refs.items()}
            fresh = run_schedule(scene, w, h, schedule, todo, displays,
                                 desc=f"{scene.name}: {protocol.name} ({', '.join(c.label for c in todo)})",
                                 progress=False)
            for c in todo:
                r = fresh[c.label]
                bad = [f for f, img in r["images"].items() if not _finite(img)]
                if bad:
                    raise TaskError(f"scene {scene.name!r}, {protocol.name}: technique {c.label!r} produced "
                                    f"NaN/Inf in frame(s) {bad[:5]}")
                meta = {"label": c.label, "technique": c.name, "overrides": [list(o) for o in c.overrides],
                        "output_space": r["output_space"], "nonfinite_inputs": r["nonfinite"],
                        "frames": sorted(r["images"]), "stats": {str(f): v for f, v in r["stats"].items()}}
                files = {f"frame_{f:04d}.exr": img for f, img in r["images"].items()}
                rec = store.save_folder(Path(folders[c.label]), keys[c.label], files, meta)
                out[c.label] = _run_summary(rec, computed=True)
    return {"kind": "run", "runs": out}


def _finite(img) -> bool:
    import numpy as np
    return bool(np.all(np.isfinite(img)))


def _run_summary(rec: dict, computed: bool) -> dict:
    return {"key": rec["key"], "frames": rec["frames"], "output_space": rec["output_space"],
            "stats": rec.get("stats", {}), "computed": computed}


# -- metrics of a run --------------------------------------------------------------------------------
@_deterministic
def metrics_task(ctx: Context, scene_spec: str, w: int, h: int, run_folder: str, run_key: str,
                 frame_times: dict, ref_settings: dict, maps_for: list, key: str, folder: str, deps=()) -> dict:
    """Metrics of every judged frame of one run against its references; maps of `maps_for`."""
    import numpy as np

    from display import DisplayTransform

    from . import metrics as M
    from .store import TamperError
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with store.lock(key):
        rec = store.done(Path(folder), key)
        if rec is not None:
            return {"kind": "metrics", "key": key, "data": _metrics_data(rec), "computed": False}
        run = store.done(Path(run_folder), run_key)
        if run is None:
            raise TaskError(f"metrics of {run_folder}: the run is not complete")
        images = {}
        try:
            for f in run["frames"]:
                ch = store.read_image(Path(run_folder), f"frame_{f:04d}.exr", run)
                images[f] = np.stack([ch[c] for c in "RGB"], -1)
        except TamperError as exc:
            store.invalidate(Path(run_folder), str(exc))
            raise TaskError(f"{exc}: the run was invalidated; run the study again to re-make it") from None
        times = {int(f): int(t) for f, t in frame_times.items()}
        refs = _references(ctx, scene, sorted(set(times.values())), w, h, ref_settings)
        displays = {t: DisplayTransform.from_reference(r.image) for t, r in refs.items()}
        per_frame, maps, seq = {}, {}, []
        for f in run["frames"]:
            t = times[f]
            ref = refs[t]
            disp = displays[t]
            ref_disp = disp.encode(ref.image)
            ref8 = np.round(ref_disp * 255.0).astype(np.uint8)   # disp.to_8bit, without encoding twice
            x = images[f]
            if run["output_space"] == "display":
                x_lin, x_disp = None, np.clip(x.astype(np.float64), 0, 1)
            else:
                x_lin, x_disp = x, disp.encode(x)
            x8 = np.round(x_disp * 255).astype(np.uint8)
            per_frame[str(f)], m = M.all_metrics(ref.image, ref_disp, ref8, x_lin, x_disp, x8)
            if f in maps_for:
                maps[f"maps_{f:04d}.exr"] = m
            seq.append((ref8, x8))
        temporal = M.temporal_instability([a for a, _ in seq], [b for _, b in seq]) if len(seq) > 1 else None
        data = {"per_frame": per_frame, "temporal": temporal,
                "references": {str(t): r.key for t, r in refs.items()}}
        rec = store.save_folder(Path(folder), key, maps, {"data": data})
    return {"kind": "metrics", "key": key, "data": _metrics_data(rec), "computed": True}


def _metrics_data(rec: dict) -> dict:
    return rec["data"]


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

