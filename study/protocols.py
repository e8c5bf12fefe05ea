"""The thesis's test protocols, driving the raster and the techniques in lockstep.

Static test (thesis 4.2.1): at one scene time, a 'sequence' technique (TAA) sees 16 frames with
Halton jitter k = 0..15 and the last output is kept; a 'centre' technique (No AA, FXAA) sees the
unjittered frame; a 'supersample' one (accumulation) its N jittered sub-frames.
Ghosting test (thesis 4.2.2): frames t = 0..N-1 of an animated scene, jitter k = t, history reset
at the first frame and at camera cuts; every frame is kept and judged against its own reference.
Raster frames are rendered once per step and shared by every technique that needs them.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from display import DisplayTransform
from raster import Rasterizer
from scenes import ResolvedScene
from scenes.jitter import TAA_PERIOD, halton_offset, halton_offsets

from .config import TechniqueConfig


@dataclass(frozen=True)
class Step:
    t: int          # scene time (animation frame)
    k: int          # jitter index of sequence techniques
    keep: bool      # output judged
    reset: bool     # history reset before this step
    prev_t: int     # scene time of the previous step: motion vectors and previous cameras refer to it


def static_schedule(t: int, history: int) -> list[Step]:
    # Every frame shows the same instant: nothing moves between them, only the jitter changes.
    return [Step(t, k, keep=(k == history - 1), reset=(k == 0), prev_t=t) for k in range(history)]


def ghosting_schedule(scene: ResolvedScene, frames: int) -> list[Step]:
    return [Step(t, t, keep=True, reset=scene.is_cut(t), prev_t=t - 1) for t in range(frames)]


def sampling_of(tech) -> str:
    return getattr(tech, "sampling", "sequence")


def run_schedule(scene: ResolvedScene, width: int, height: int, schedule: list[Step],
                 configs: list[TechniqueConfig], displays: dict[int, DisplayTransform],
                 desc: str = "", progress: bool = True) -> dict[str, dict]:
    """Run techniques over a schedule. Returns label -> {images: {t: image}, output_space, ms}."""
    techs = {c.label: c.make() for c in configs}
    needs = set().union(*(t.needs for t in techs.values())) | {"color"}
    out = {c.label: {"images": {}, "times": [], "output_space": getattr(techs[c.label], "output_space", "linear"),
                     "nonfinite": 0, "stats": {}} for c in configs}
    far = scene.desc.camera.far
    first_kept = True   # single-image techniques run twice there, so their time excludes the compile
    raster = Rasterizer(scene, width, height)
    try:
        for step in tqdm(schedule, desc=desc or scene.name, unit="frame", disable=not progress,
                         leave=False, mininterval=1.0):
            seq_frame = centre_frame = None
            for label, tech in techs.items():
                mode = sampling_of(tech)
                if mode != "sequence" and not step.keep:
                    continue
                kwargs = {"far": far, "reset": step.reset}
                if getattr(tech, "output_space", "linear") == "display":
                    kwargs["display"] = displays[step.t]
                if getattr(tech, "needs_cameras", False):   # e.g. motion from depth and camera only
                    kwargs["cameras"] = (scene.camera(step.t, width, height),
                                         scene.camera(step.prev_t, width, height))
                if mode == "sequence":
                    if seq_frame is None:
                        jit = halton_offset(step.k, TAA_PERIOD)
                        seq_frame = (raster.render(step.t, jit, tuple(needs), prev_t=step.prev_t), jit)
                    frame, jit = seq_frame
                    t0 = time.perf_counter()
                    if getattr(tech, "supersampling", False):
                        # Sparse supersampling: the technique marks pixels its history cannot
                        # serve; only those get extra samples (timed as raster work, not here).
                        mask = tech.invalid_mask(frame, far=far) if not step.reset else \
                            np.ones(frame["color"].shape[:2], bool)
                        t_mask = time.perf_counter() - t0
                        n = int(getattr(tech.params, "samples", 8))
                        ss, ss_stats = raster.supersample(step.t, mask, halton_offsets(n))
                        t0 = time.perf_counter() - t_mask
                        img = tech.process(frame, jitter=jit, supersampled=ss, mask=mask, **kwargs)
                        if step.keep:
                            out[label]["stats"][step.t] = {**getattr(tech, "last_stats", {}), **ss_stats}
                    else:
                        img = tech.process(frame, jitter=jit, **kwargs)
                elif mode == "centre":
                    if centre_frame is None:
                        centre_frame = raster.render(step.t, (0.0, 0.0), tuple(needs), prev_t=step.prev_t)
                    if first_kept:
                        tech.process(centre_frame, jitter=(0.0, 0.0), **kwargs)
                    t0 = time.perf_counter()
                    img = tech.process(centre_frame, jitter=(0.0, 0.0), **kwargs)
                elif mode == "supersample":
                    n = int(tech.params.samples)
                    subs = [raster.render(step.t, halton_offset(j, n), tuple(needs), prev_t=step.prev_t)
                            for j in range(n)]
                    if first_kept:
                        tech.process_samples(subs)
                    t0 = time.perf_counter()
                    img = tech.process_samples(subs)
                else:
                    raise ValueError(f"technique {label!r} has unknown sampling {mode!r}")
                out[label]["times"].append(time.perf_counter() - t0)
                out[label]["nonfinite"] += int(getattr(tech, "last_nonfinite_count", 0))
                if step.keep:
                    out[label]["images"][step.t] = np.asarray(img, np.float32)
            if step.keep:
                first_kept = False
    finally:
        raster.close()
    for label, r in out.items():
        times = r.pop("times")
        warm = times[2:] if len(times) > 2 else times   # the first calls compile kernels
        r["ms"] = 1000 * statistics.median(warm)
    return out
