"""The video metric task: one test's runs judged by ColorVideoVDP (study.metrics.video), once its
references are final (study.engine.runner plans it in a study's last round: the metric costs
~100x an image metric, and the precision rounds' coarser references would each need it again).

A ghosting test's judged frames are one video per technique, played at the study's frame rate; a
static test's views (its thesis and converged history lengths) are image pairs. Like every
figure, each JOD is judged against the reference and against its two independent halves, and
filed with the reference's bias removed and the uncertainty that leaves (study.metrics.uncertainty).
"""
from __future__ import annotations

import contextlib
from pathlib import Path

from study.engine.judge import HALVES, judged_references, locked_records
from study.engine.tasks import TaskError, _deterministic, _setup, display_of, load_scene
from study.metrics import uncertainty as U


@_deterministic
def video_task(ctx, scene_spec: str, w: int, h: int, items: list, ref_settings: dict, display_settings: dict,
               video: dict, kind: str, deps=()) -> dict:
    """items: one per technique, {run_folder, run_key, frame_times (frame id -> scene time),
    frames (the judged frame ids: a ghosting test's in order, a static test's views), key, folder}.
    `ref_settings`: scene time -> its reference's settings. `video`: study.config.video.Video.task_data().
    Returns the records by key."""
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with contextlib.ExitStack() as locks:
        records, todo = locked_records(store, items, locks)
        for it, data in _judge(store, ctx, scene, w, h, todo, ref_settings, display_settings, video, kind):
            records[it["key"]] = {"data": data, "computed": True}
    return {"kind": "video", "records": records}


def _judge(store, ctx, scene, w, h, items, ref_settings, display_settings, video, kind):
    import numpy as np

    from references import ReferenceCache
    from study.engine.store import TamperError
    from study.metrics.video import metric
    if not items:
        return
    vdp = metric(video["display"], ctx.threads, video.get("device", "auto"))
    cache = ReferenceCache(Path(ctx.cache_root))
    refs8: dict = {}         # scene time -> {half: 8-bit reference}, read once for every technique
    disps: dict = {}
    for it in items:
        # a static run keeps the views' frames (those judged here); a ghosting one keeps all
        run = store.done(Path(it["run_folder"]), it["run_key"], whole=kind == "ghosting")
        if run is None:
            raise TaskError(f"video metric of {it['run_folder']}: the run is not complete")
        times = {int(f): int(t) for f, t in it["frame_times"].items()}
        frames = [int(f) for f in it["frames"]]
        x8 = {}
        for f in frames:
            t = times[f]
            if t not in refs8:
                ref = cache.get(scene, t, w, h, **ref_settings[t])[0]
                disps[t] = display_of(cache, scene, t, w, h, display_settings)
                refs8[t] = {hv: r[2] for hv, r in judged_references(ref, disps[t]).items()}
            try:
                ch = store.read_image(Path(it["run_folder"]), f"frame_{f:04d}.exr", run)
            except TamperError as exc:
                store.invalidate(Path(it["run_folder"]), str(exc))
                raise TaskError(f"{exc}: the run was invalidated; run the study again to re-make it") from None
            x8[f] = disps[t].output(np.stack([ch[c] for c in "RGB"], -1), run["output_space"])[2]
        figures, maps = {}, {}
        # a ghosting test is one video; a static test's views are image pairs, each on its own
        groups = [("sequence", frames)] if kind == "ghosting" else [(str(f), [f]) for f in frames]
        for name, fs in groups:
            test = np.stack([x8[f] for f in fs])
            q = {}
            for hv in HALVES:
                ref = np.stack([refs8[times[f]][hv] for f in fs])
                q[hv], hmap = vdp.jod(test, ref, video["fps"], heatmap=hv == "")
                if hv == "":
                    maps[f"maps_{fs[-1]:04d}.exr"] = {"cvvdp": hmap}
            c, u = U.jackknife(*({"jod": q[hv]} for hv in HALVES))
            figures[name] = (c["jod"], u["jod"], q)
        data = {"jod": {k: v for k, (v, _, _) in figures.items()}, "jod_u": {k: u for k, (_, u, _) in figures.items()},
                # as judged against the reference ("") and each half, before the bias is removed
                "jod_judged": {k: q for k, (_, _, q) in figures.items()}, **video}
        rec = store.save_folder(Path(it["folder"]), it["key"], maps, {"data": data})
        yield it, rec["data"]
