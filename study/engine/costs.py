"""What each technique costs per output frame, measured serially (never beside other work, so a
parallel study does not time contention).

A technique's frame costs the samples it shades plus its resolve (docs/method.md): No AA, FXAA,
SMAA and the TAAs shade one sample per pixel, SSAA N, sparse supersampling 1 plus the extra
samples its mask asked for in the run (measured there). So per scene we time, on this machine:
  raster_ms     one raster frame of the buffers the technique reads (visibility + reconstruction
                + shading: the cost of one sample per pixel), at its render size (an upscaler's
                render_scale x the output: render_scale^2 samples per output pixel);
  extra_ms      for sparse supersampling, its supersample call on the mask of a converged frame,
                scaled to the mean extra samples the run recorded;
  resolve_ms    the technique's own work per frame (process), warm;
  total_ms      raster_ms x subframes + extra_ms + resolve_ms.
All are medians of repeated warm calls (the first calls compile kernels).
"""
from __future__ import annotations

import platform
import statistics
import time

import numpy as np

from scenes.jitter import TAA_PERIOD, halton_offset, halton_offsets

from study.config.protocols import Step, step_jitters
from study.engine.drive import FrameSource, drive

REPEATS = 3       # warm calls a median is taken over: 182 (scene, column) pairs in the quick study
DISTINCT_SUBFRAMES = 4     # rendered sub-frames a supersampling technique's resolve is timed on


def median_ms(fn, repeats: int = REPEATS, warmup: int = 1) -> float:
    """Median wall time of `fn` in ms over `repeats` calls after `warmup` (compiling) calls."""
    times = []
    for i in range(warmup + repeats):
        t0 = time.perf_counter()
        fn()
        if i >= warmup:
            times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times)


def machine() -> dict:
    import backend
    return {"host": platform.node(), "cpu": platform.processor() or platform.machine(),
            "variant": backend.VARIANT}


class Sources:
    """The frame sources of one scene's cost measurements and their raster times, one per (render
    size, buffers): the columns reading the same buffers at the same size (the TAAs and their
    variants) share one rasteriser and one raster timing instead of each making and timing its own."""

    def __init__(self):
        self._by: dict = {}

    def get(self, scene, width: int, height: int, inp) -> tuple:
        k = (scene.content_hash, width, height, inp.render_scale, tuple(sorted(set(inp.buffers) | {"color"})))
        if k not in self._by:
            src = FrameSource.for_output(scene, width, height, inp.render_scale, inp.buffers)  # an upscaler's: smaller
            raster_ms = median_ms(lambda: src.raster.render(0, halton_offset(3, TAA_PERIOD), src.buffers, prev_t=0))
            self._by[k] = (src, raster_ms)
        return self._by[k]

    def close(self):
        for src, _ in self._by.values():
            src.close()
        self._by.clear()


def measure(scene, width: int, height: int, configs: list, displays: dict, extra_spp: dict,
            sources: Sources | None = None) -> dict:
    """`extra_spp`: label -> mean extra samples per pixel its run shaded (sparse supersampling).
    `sources`: kept across calls for one scene (the caller closes it); else made and closed here."""
    out = {}
    own = sources is None
    sources = Sources() if own else sources
    for c in configs:
        tech = c.make()
        inp = tech.inputs
        src, raster_ms = sources.get(scene, width, height, inp)
        try:
            first = Step(0, 0, keep=True, reset=True, prev_t=0, frame=1)
            if inp.sampling == "supersample":
                # The resolve (a mean) costs the same whatever its sub-frames show: a few rendered
                # ones, each sub-frame a copy of one in its own memory as N rendered frames are,
                # not N renders twice (a warm-up drive, then the list): 2 x 128 raster frames a
                # scene for the thesis's 128-sample accumulation were most of the serial costs.
                jits = step_jitters(first, "supersample", inp.subframes)
                base = [src.frame(0, j, 0) for j in jits[:DISTINCT_SUBFRAMES]]
                subs = [{k: base[i % len(base)][k].copy() for k in tech.needs} for i in range(len(jits))]
                resolve_ms = median_ms(lambda: tech.process(samples=subs, far=scene.desc.camera.far))
                del subs, base
            else:
                drive(tech, first, src, scene, width, height, displays.get(0))   # fills the history, as the kernels expect
                (jit,) = step_jitters(Step(0, 1, keep=True, reset=False, prev_t=0, frame=2), inp.sampling,
                                      period=inp.jitter_period)
                frame = src.frame(0, jit, 0)
                kw = {"far": scene.desc.camera.far}
                if inp.upsamples:
                    kw["output_size"] = (width, height)
                if inp.display:
                    kw["display"] = displays.get(0)
                if inp.cameras:
                    kw["cameras"] = (scene.camera(0, width, height), scene.camera(0, width, height))
                if inp.extra_samples:
                    # Its mask depends on its history, so each call makes it (the technique's work);
                    # the extra samples' shading is extra_ms below.
                    def step():
                        mask = tech.invalid_mask(frame, far=kw["far"])
                        tech.process(frame, jitter=jit, supersampled=frame["color"], mask=mask, **kw)
                    resolve_ms = median_ms(step)
                else:
                    resolve_ms = median_ms(lambda: tech.process(frame, jitter=jit, **kw))
            extra_ms = 0.0
            if inp.extra_samples:
                frac = float(extra_spp.get(c.label, 0.0))
                n_pix = max(1, int(round(frac * width * height / max(inp.extra_samples, 1))))
                rng = np.random.default_rng(0)
                mask = np.zeros((height, width), bool)
                mask.ravel()[rng.choice(width * height, min(n_pix, width * height), replace=False)] = True
                offs = halton_offsets(inp.extra_samples)
                extra_ms = median_ms(lambda: src.raster.supersample(0, mask, offs, reuse=False), repeats=3, warmup=1)
            spp = inp.shaded_samples(float(extra_spp.get(c.label, 0.0)) / inp.extra_samples
                                     if inp.extra_samples else 0.0)
            out[c.label] = {"raster_ms": raster_ms, "resolve_ms": resolve_ms, "extra_ms": extra_ms,
                            "samples_per_pixel": spp, "render_scale": inp.render_scale,
                            "total_ms": raster_ms * inp.subframes + extra_ms + resolve_ms}
        finally:
            if own:
                sources.close()
    return out


def measure_study(cache_root, scenes, statics, records_of, display_of, progress: bool = True) -> dict:
    """(scene, column label) -> cost record of every static test's column: cached by scene, size,
    technique (code included), this machine and the extra samples its run shaded; the missing
    ones measured one after another. `records_of(test)`: label -> its run's done record;
    `display_of(scene, t, w, h)`: frame t's display transform."""
    import sys

    from provenance import code_snapshot, task_key
    from study.engine.store import Store
    from study.engine.tasks import _deterministic
    store, mach, out, todo = Store(cache_root), machine(), {}, []
    by_name = {scene.name: scene for _, scene in scenes}
    with code_snapshot():           # one state of the code for every cost's key
        for test in statics:
            scene, recs = by_name[test.scene], records_of(test)
            for c in test.configs:
                stats = (recs[c.label] or {}).get("stats") or {}
                extra = sum(v["samples_shaded"] for v in stats.values()) / len(stats) / (test.width * test.height) \
                    if stats else 0.0
                key = task_key("cost", {"scene": scene.content_hash, "res": (test.width, test.height),
                                        "technique": c.key_data(), "machine": mach, "extra_spp": round(extra, 3)},
                               code=[c.code(), "study.engine.costs"])
                path = store.record_path("costs", test.scene, key)
                rec = store.load_record(path, key)
                if rec is None:
                    todo.append((test, scene, c, extra, key, path))
                else:
                    out[(test.scene, c.label)] = rec
    if todo:
        from tqdm import tqdm
        refs, sources = {}, Sources()
        try:
            for test, scene, c, extra, key, path in tqdm(todo, desc="costs (serial)", unit="technique",
                                                          disable=not progress, file=sys.stderr):
                if test.scene not in refs:
                    sources.close()          # todo is in scene order: one scene's rasterisers at a time
                    refs[test.scene] = display_of(scene, 0, test.width, test.height)
                got = _deterministic(measure)(scene, test.width, test.height, [c], {0: refs[test.scene]},
                                              {c.label: extra}, sources)[c.label]
                out[(test.scene, c.label)] = store.save_record(path, key, got)
        finally:
            sources.close()
    return out
