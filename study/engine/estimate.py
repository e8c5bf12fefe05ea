"""What a planned study will compute, in work units, and what those units cost on this machine.

`work(plan)` counts, per scene, what the plan's tasks will do (only tasks not already complete in
the cache): references to render, distinct raster frames, technique steps (process calls), judged
technique-frames (the metrics' unit) and agreement checks. `measure_units` times one of each unit
per scene here (a reference of frame 0 through the cache, so a measured reference is not wasted;
raster and resolve through study.engine.costs; the metrics of one technique-frame, split into its
per-reference and per-frame parts as study.engine.judge works; writing, hashing and reading back one
frame, for the judged frames a run writes: not those its run task judges as it makes them), and
`estimate` multiplies. It is an extrapolation: a moving scene's references are assumed to cost what its
frame 0 costs, and sparse supersampling's extra samples are taken at the share its mask asks for
on a converged frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from study.config.protocols import frame_key, judged_steps, step_jitters
from taa_impl.upscale import render_size


@dataclass
class SceneWork:
    scene: str
    spec: str
    width: int
    height: int
    references: int = 0
    raster_frames: float = 0                               # distinct 1-spp raster frames (output-size equivalents)
    steps: dict = field(default_factory=dict)              # label -> process calls
    subframes: dict = field(default_factory=dict)          # label -> supersample sub-frames rendered
    judged: dict = field(default_factory=dict)             # label -> technique-frames judged
    written: int = 0                                       # of those, written by their run and read back
    reference_reads: int = 0                               # references the metrics tasks read (once each)
    agreement_frames: int = 0                               # raster frames the agreement check averages
    configs: dict = field(default_factory=dict)            # label -> TechniqueConfig
    run_memory: int = 0                                    # bytes the largest run task holds (run_memory)


def _get(out: dict, spec: str, scene, w: int, h: int) -> SceneWork:
    return out.setdefault(scene.name, SceneWork(scene.name, spec, w, h))


def work(plan, cache=None) -> dict[str, SceneWork]:
    """Per scene, the units the plan's tasks will compute (a reference `cache` holds is no work)."""
    from shading.mips import has_trilinear
    from study.engine.tasks import load_scene
    out: dict[str, SceneWork] = {}
    # metrics judged by their run task as it makes the run (study.engine.run_task): no frame written
    streamed = {it["key"] for t in plan.tasks.values() if t.kind == "run" for g in (t.spec.judge or [])
                for it in g["items"]}
    for task in plan.tasks.values():
        s = task.spec
        spec, w, h = s.scene, s.width, s.height
        if task.kind == "reference":
            scene = load_scene(spec)
            sw = _get(out, spec, scene, w, h)
            if cache is None or not cache.has(scene, s.t, w, h, **s.settings):
                sw.references += 1
        elif task.kind == "agreement":
            _get(out, spec, load_scene(spec), w, h).agreement_frames += s.samples + 1
        elif task.kind == "run":
            scene = load_scene(spec)
            sw = _get(out, spec, scene, w, h)
            schedule = s.protocol.schedule(scene)
            for c in s.configs:
                inp = c.inputs()
                sw.configs[c.label] = c
                steps = schedule if inp.sampling == "sequence" else judged_steps(schedule, inp.sampling)
                sw.steps[c.label] = sw.steps.get(c.label, 0) + len(steps)
                if inp.sampling == "supersample":
                    sw.subframes[c.label] = sw.subframes.get(c.label, 0) + len(steps) * inp.subframes
            frames, buffers = raster_frames(schedule, s.configs, w, h, has_trilinear(scene))
            # a frame below the output's size costs its share of the pixels (an upscaler's)
            sw.raster_frames += round(sum(f[0][0] * f[0][1] for f in frames) / (w * h), 3)
            sw.run_memory = max(sw.run_memory, run_memory(w, h, frames, buffers, len(s.configs)))
        elif task.kind == "metrics":
            sw = _get(out, spec, load_scene(spec), w, h)
            for it in s.items:
                sw.judged[it["label"]] = sw.judged.get(it["label"], 0) + len(it["frame_times"])
                sw.written += 0 if it["key"] in streamed else len(it["frame_times"])
            sw.reference_reads += len({t for it in s.items for t in it["frame_times"].values()})
    return out


def raster_frames(schedule: list, configs: list, w: int, h: int, biased: bool) -> tuple[set, dict]:
    """The distinct raster frames a run of `configs` over `schedule` at w x h renders, as
    study.engine.drive.FrameSource memoises them (one source per render size, and per LOD bias where
    a texture is trilinear: `biased`), as (size, time, jitter x, jitter y, previous time, bias) keys;
    and (size, bias) -> the buffers those frames hold. A supersampling column's sub-frames are not
    kept, so not here."""
    from study.config.techniques import lod_bias
    frames, buffers = set(), {}
    for c in configs:
        inp = c.inputs()
        if inp.sampling not in ("sequence", "centre"):
            continue
        steps = schedule if inp.sampling == "sequence" else judged_steps(schedule, inp.sampling)
        size = render_size(w, h, inp.render_scale)
        bias = lod_bias(c) if biased else 0.0
        frames |= {(size, *frame_key(s.t, j, s.prev_t), bias) for s in steps
                   for j in step_jitters(s, inp.sampling, period=inp.jitter_period)}
        buffers.setdefault((size, bias), set()).update(inp.buffers)
    return frames, buffers


# What a run task holds for each column besides the frames it keeps: a history of one colour (the
# measured peak RSS of the thesis's ten columns on hairball_lit at 1600x900 was 2.14 GB, this model
# 2.25; docs/performance.md, "Memory")
COLUMN_BYTES_PER_PIXEL = 12


def run_memory(width: int, height: int, frames: set, buffers: dict, columns: int) -> int:
    """Bytes a run task holds at its peak (study.engine.drive): the raster frames its sources keep
    at once (those of one scene time: earlier times are dropped as a sequence moves; `frames` holds
    (size, time, jitter x, jitter y, previous time, bias) keys, `buffers` (size, bias) -> the
    buffers kept), one render in flight (raster.limits), and each column's share."""
    from raster.limits import frame_bytes, memory_need
    held: dict = {}
    for size, t, *_, bias in frames:
        held.setdefault((size, bias), {}).setdefault(t, 0)
        held[(size, bias)][t] += 1
    kept = sum(max(per_t.values()) * frame_bytes(*size, buffers[(size, bias)])
               for (size, bias), per_t in held.items())
    return memory_need(width, height) + kept + columns * COLUMN_BYTES_PER_PIXEL * width * height


def measure_units(sw: SceneWork, ref_settings: dict, cache, configs: list) -> dict:
    """Seconds of one unit of each kind for this scene, measured here (see the module docstring)."""
    import numpy as np

    from display import DisplayTransform
    from study.engine import costs as C
    from study.metrics import judging as M
    from study.engine.judge import judged_references
    from study.engine.tasks import load_scene
    scene = load_scene(sw.spec)
    ref, cached = cache.get(scene, 0, sw.width, sw.height, **ref_settings)
    disp = DisplayTransform.from_reference(ref.image)
    measured = C.measure(scene, sw.width, sw.height, configs, {0: disp}, {})
    # the metrics task's two parts (study.engine.judge): per reference (read, display transform, encode,
    # quantise) and per technique-frame (encode, judge), here on a noisy copy of the reference
    x = (ref.image * (1 + 0.05 * np.random.default_rng(0).standard_normal(ref.image.shape))).astype(np.float32)
    got = {}

    def per_reference():       # as study.engine.judge: from the cache (now a read), the reference and its halves
        r = cache.get(scene, 0, sw.width, sw.height, **ref_settings)[0]
        d = DisplayTransform.from_reference(r.image)
        got["refs"] = list(judged_references(r, d).values())

    memos: list = [{}, {}, {}]

    def per_frame():   # judged against all three; after the first, FLIP's reference half comes from the memo
        out = disp.output(x, "linear")
        for (lin, e, r8), memo in zip(got["refs"], memos):
            M.all_metrics(lin, e, r8, *out, want_maps=False, memo=memo)
    reference_read_s = C.median_ms(per_reference, repeats=3, warmup=1) / 1000
    metrics_s = C.median_ms(per_frame, repeats=3, warmup=1) / 1000
    # each judged frame is written by its run (and hashed) and read back by the metrics task
    import tempfile
    from pathlib import Path

    from references.exr import read_exr, write_exr

    from study.engine.store import sha256_file
    with tempfile.TemporaryDirectory() as tmp:
        frame = Path(tmp) / "frame.exr"

        def frame_io():
            write_exr(frame, {"RGB": ref.image})      # real content (noise compresses worse)
            sha256_file(frame)
            sha256_file(frame)
            read_exr(frame)
        frame_io_s = C.median_ms(frame_io, repeats=3, warmup=1) / 1000
    return {"reference_s": ref.seconds, "reference_cached": cached, "metrics_s": metrics_s,
            "reference_read_s": reference_read_s, "frame_io_s": frame_io_s,
            "raster_s": min(m["raster_ms"] for m in measured.values()) / 1000,
            "resolve_s": {label: m["resolve_ms"] / 1000 for label, m in measured.items()},
            "subframe_s": {label: m["raster_ms"] / 1000 for label, m in measured.items()}}


def estimate(sw: SceneWork, units: dict) -> dict:
    """Seconds per kind of work for one scene: units x unit costs."""
    res = units["resolve_s"]
    out = {"reference": sw.references * units["reference_s"],
           "raster": sw.raster_frames * units["raster_s"]
           + sum(n * units["subframe_s"].get(label, units["raster_s"]) for label, n in sw.subframes.items()),
           "resolve": sum(n * res.get(label, 0.0) for label, n in sw.steps.items()),
           "metrics": sum(sw.judged.values()) * units["metrics_s"] + sw.reference_reads * units["reference_read_s"],
           "frame_io": sw.written * units["frame_io_s"],
           "agreement": sw.agreement_frames * units["raster_s"]}
    out["total"] = sum(out.values())
    return out

