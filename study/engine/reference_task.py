"""The reference task: one (scene, frame) rendered to its per-pixel bound, or read from the cache
(with settings `reuse`, keeping frame t - 1's pixels that nothing changes: references.reuse; the
planner makes it run after frame t - 1's)."""
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
    # `traced`: the samples this frame's render traced (a reused pixel's were traced for an earlier frame)
    return {"kind": "reference", "key": ref.key, "t": t, "rendered": not cached, "spp": ref.spp,
            "seconds": ref.seconds, "noise_psnr_db": ref.noise_psnr_db, "traced": ref.traced,
            "reused": 0 if ref.reused is None else int(ref.reused.sum())}
