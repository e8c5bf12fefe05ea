"""The reference task: one (scene, frame) rendered to its per-pixel bound, or read from the cache."""
from __future__ import annotations

from pathlib import Path

from provenance import task_key
from study.engine.tasks import Context, _deterministic, _setup, load_scene


@_deterministic
def reference_task(ctx: Context, scene_spec: str, t: int, w: int, h: int, settings: dict) -> dict:
    from references import ReferenceCache
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with store.lock(task_key("reference-lock", (scene.content_hash, t, w, h, settings))):
        ref, cached = ReferenceCache(Path(ctx.cache_root)).get(scene, t, w, h, **settings)
    return {"kind": "reference", "key": ref.key, "t": t, "rendered": not cached, "spp": ref.spp,
            "seconds": ref.seconds, "noise_psnr_db": ref.noise_psnr_db}
