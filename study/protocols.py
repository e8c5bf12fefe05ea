"""The test protocols, and the driver that runs techniques over them in lockstep with the raster.

Static test (thesis 4.2.1), parameter `history`: at one scene time a 'sequence' technique (TAA)
sees `history` frames with Halton jitter k = 0, 1, ... from a reset; its output is judged at each
of `checkpoints` (history lengths; the thesis keeps 16). One run of the longest history gives every
shorter one, so the convergence study and the thesis's protocol come from the same frames. A
'centre' technique (No AA, FXAA, SMAA) sees the unjittered frame, a 'supersample' one
(accumulation) its N jittered sub-frames; they have no history and are judged once.
Ghosting test (thesis 4.2.2), parameters `frames` and `warmup`: `warmup` frames at the first
instant (the scene does not move yet; not judged), then scene times t = 0..frames-1, jitter
continuing, history reset at camera cuts; every frame t is judged against its own reference.
The thesis's protocol is a cold start (warmup 0).

A static scene's frames repeat with the jitter's period (16): the driver renders each distinct
(time, jitter) raster frame once and reuses it, so 256 frames of history cost 16 raster frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from display import DisplayTransform
from raster import Rasterizer
from scenes import ResolvedScene
from scenes.jitter import TAA_PERIOD, halton_offset, halton_offsets




@dataclass(frozen=True)
class Step:
    t: int          # scene time (animation frame)
    k: int          # jitter index of sequence techniques
    keep: bool      # output judged
    reset: bool     # history reset before this step
    prev_t: int     # scene time of the previous step: motion vectors and previous cameras refer to it
    frame: int = -1  # id a kept output is filed under: history length (static) or scene time (ghosting)


@dataclass(frozen=True)
class Protocol:
    """A test and its parameters. `name` labels it in tables."""
    name: str
    kind: str                          # 'static' | 'ghosting'
    history: int = 16                  # static: frames of history of the longest run
    checkpoints: tuple = (16,)         # static: history lengths judged
    frames: int = 24                   # ghosting: judged frames (capped by the scene's own)
    warmup: int = 0                    # ghosting: unjudged frames at the first instant

    def __post_init__(self):
        if self.kind not in ("static", "ghosting"):
            raise ValueError(f"protocol {self.name!r}: kind must be 'static' or 'ghosting', got {self.kind!r}")
        if self.kind == "static":
            bad = [c for c in self.checkpoints if not 1 <= int(c) <= self.history]
            if self.history < 1 or not self.checkpoints or bad:
                raise ValueError(f"protocol {self.name!r}: need history >= 1 and checkpoints in 1..history, "
                                 f"got history {self.history}, checkpoints {list(self.checkpoints)}")
        elif self.frames < 1 or self.warmup < 0:
            raise ValueError(f"protocol {self.name!r}: need frames >= 1 and warmup >= 0, "
                             f"got {self.frames}, {self.warmup}")

    def schedule(self, scene: ResolvedScene) -> list[Step]:
        if self.kind == "static":
            return static_schedule(0, self.history, self.checkpoints)
        return ghosting_schedule(scene, min(scene.desc.frames, self.frames), self.warmup)


def static_schedule(t: int, history: int, checkpoints=None) -> list[Step]:
    # Every frame shows the same instant: nothing moves between them, only the jitter changes.
    keep = set(checkpoints or (history,))
    return [Step(t, k, keep=(k + 1) in keep, reset=(k == 0), prev_t=t, frame=k + 1) for k in range(history)]


def ghosting_schedule(scene: ResolvedScene, frames: int, warmup: int = 0) -> list[Step]:
    warm = [Step(0, k, keep=False, reset=(k == 0), prev_t=0) for k in range(warmup)]
    # After a warm-up, frame 0 continues the warm history (is_cut(0) means "first frame").
    return warm + [Step(t, warmup + t, keep=True, reset=scene.is_cut(t) and not (t == 0 and warmup),
                        prev_t=max(t - 1, 0) if warmup else t - 1, frame=t) for t in range(frames)]


def judged_steps(schedule: list[Step], sampling: str) -> list[Step]:
    """The steps whose output a technique is judged at. Without history the output depends on the
    scene time alone, so a technique of 'centre'/'supersample' sampling is judged once per time."""
    kept = [s for s in schedule if s.keep]
    if sampling == "sequence":
        return kept
    last = {}
    for s in kept:
        last[s.t] = s
    return list(last.values())


class FrameSource:
    """Raster frames of one scene, each distinct (time, jitter, previous time) rendered once."""

    def __init__(self, scene: ResolvedScene, width: int, height: int, buffers):
        self.raster = Rasterizer(scene, width, height)
        self.buffers = tuple(sorted(set(buffers) | {"color"}))
        self._memo: dict = {}
        self.rendered = 0

    def frame(self, t: int, jitter, prev_t: int) -> dict:
        key = (t, round(float(jitter[0]), 9), round(float(jitter[1]), 9), prev_t)
        if key not in self._memo:
            self._memo[key] = self.raster.render(t, jitter, self.buffers, prev_t=prev_t)
            self.rendered += 1
        return self._memo[key]

    def forget_before(self, t: int) -> None:
        """Frames of earlier scene times are not asked for again in a moving sequence."""
        for key in [k for k in self._memo if k[0] < t]:
            del self._memo[key]

    def close(self):
        self.raster.close()


def drive(tech, step: Step, src: FrameSource, scene: ResolvedScene, width: int, height: int,
          display: DisplayTransform | None):
    """One step of one technique: the inputs it declares, then `process`. Returns (image, stats)."""
    inp = tech.inputs
    far = scene.desc.camera.far
    kwargs = {"far": far, "reset": step.reset}
    if inp.display:
        kwargs["display"] = display
    if inp.cameras:
        kwargs["cameras"] = (scene.camera(step.t, width, height), scene.camera(step.prev_t, width, height))
    if inp.sampling == "sequence":
        jit = halton_offset(step.k, TAA_PERIOD)
        frame = src.frame(step.t, jit, step.prev_t)
        if inp.extra_samples:
            # Sparse supersampling: extra samples only where the history cannot serve the pixel.
            mask = np.ones(frame["color"].shape[:2], bool) if step.reset else tech.invalid_mask(frame, far=far)
            ss, ss_stats = src.raster.supersample(step.t, mask, halton_offsets(inp.extra_samples))
            img = tech.process(frame, jitter=jit, supersampled=ss, mask=mask, **kwargs)
            return img, {**getattr(tech, "last_stats", {}), **ss_stats}
        return tech.process(frame, jitter=jit, **kwargs), {}
    if inp.sampling == "centre":
        return tech.process(src.frame(step.t, (0.0, 0.0), step.prev_t), jitter=(0.0, 0.0), **kwargs), {}
    if inp.sampling == "supersample":
        subs = [src.frame(step.t, halton_offset(j, inp.subframes), step.prev_t) for j in range(inp.subframes)]
        img = tech.process_samples(subs)
        for j in range(inp.subframes):   # sub-frames are not shared with later steps
            src._memo.pop((step.t, *(round(float(v), 9) for v in halton_offset(j, inp.subframes)), step.prev_t), None)
        return img, {}
    raise ValueError(f"technique {tech.name!r} has unknown sampling {inp.sampling!r}")


def run_schedule(scene: ResolvedScene, width: int, height: int, schedule: list[Step],
                 configs: list, displays: dict[int, DisplayTransform],
                 desc: str = "", progress: bool = True, emit=None) -> dict[str, dict]:
    """Run techniques over a schedule. Returns label -> {images: {frame id: image}, output_space,
    nonfinite, stats: {frame id: counters}}. With `emit(label, frame id, image)`, each judged image
    is handed to it as it is made and not kept ('images' stays empty): 100 frames of ten
    techniques at 1600x900 would hold 17 GB. Timing is not measured here (see study.costs)."""
    techs = {c.label: c.make() for c in configs}
    needs = set().union(*(t.inputs.buffers for t in techs.values()))
    judged = {label: {s.frame for s in judged_steps(schedule, t.inputs.sampling)} for label, t in techs.items()}
    out = {label: {"images": {}, "output_space": t.output_space, "nonfinite": 0, "stats": {}}
           for label, t in techs.items()}
    src = FrameSource(scene, width, height, needs)
    last_t = None
    try:
        for step in tqdm(schedule, desc=desc or scene.name, unit="frame", disable=not progress,
                         leave=False, mininterval=1.0):
            if last_t is not None and step.t != last_t:
                src.forget_before(step.t)
            last_t = step.t
            for label, tech in techs.items():
                if tech.inputs.sampling != "sequence" and step.frame not in judged[label]:
                    continue
                img, stats = drive(tech, step, src, scene, width, height, displays.get(step.t))
                out[label]["nonfinite"] += int(getattr(tech, "last_nonfinite_count", 0))
                if step.frame in judged[label] and step.keep:
                    if emit is None:
                        out[label]["images"][step.frame] = np.asarray(img, np.float32)
                    else:
                        emit(label, step.frame, np.asarray(img, np.float32))
                    if stats:
                        out[label]["stats"][step.frame] = stats
    finally:
        src.close()
    return out
