"""The driver: techniques run over a protocol's schedule in lockstep with the raster.

Each distinct raster frame (study.config.protocols.frame_key) is rendered once and reused while
its scene time lasts; a supersampling technique's sub-frames are not shared with later steps.
Columns share frames of one render size; in a scene with trilinear textures, only columns of one
texture LOD bias (study.config.lod) do, since the bias changes those frames.
"""
from __future__ import annotations

import dataclasses
import inspect
import traceback
from collections.abc import Sequence

import numpy as np
from tqdm import tqdm

from backend import aligned
from display import DisplayTransform
from raster import Rasterizer
from raster.visibility import RasterError
from scenes import ResolvedScene
from scenes.jitter import halton_offsets
from taa_impl import sanitize
from taa_impl.contract import Frame, render_size

from shading.mips import has_trilinear
from study.config.protocols import Step, frame_key, judged_steps, step_jitters
from study.config.lod import lod_bias


class TechniqueError(ValueError):
    """A technique's code failed on a frame (study.engine.tasks reports it as the task's error)."""


def _source(tech) -> str:
    """'file:Class' of a technique: a user's file by its path, not its loader's module name."""
    try:
        src = inspect.getfile(type(tech))
    except (TypeError, OSError):
        src = type(tech).__module__
    return f"{src}:{type(tech).__name__}"


def _failure(scene: str, label: str, tech, step: Step, exc: Exception) -> str:
    where = traceback.extract_tb(exc.__traceback__)
    at = f" ({where[-1].filename}:{where[-1].lineno})" if where else ""
    return (f"technique {label!r} ({_source(tech)}) failed on scene {scene!r}, frame {step.frame} "
            f"(step {step.k}): {type(exc).__name__}: {exc}{at}")


def checked_output(img, scene: str, label: str, tech, step: Step, width: int, height: int) -> np.ndarray:
    """A technique's output as float32 (H, W, 3) at the output size, or a TechniqueError naming the
    column, its file and class, the scene and frame, and what was expected and got: an image of
    another shape would be written past its end or judged against the wrong pixels; one with NaN/Inf
    would spread them into the metrics, and into every later frame through the history (refused on
    the frame that made it, not at the next judged one: a 256-frame run's first judged frame is its
    16th)."""
    def bad(what: str):
        return TechniqueError(f"technique {label!r} ({_source(tech)}) {what} on scene {scene!r}, frame {step.frame} "
                              f"(step {step.k})")
    try:
        out = np.asarray(img, np.float32)
    except (TypeError, ValueError) as exc:
        raise bad(f"returned {type(img).__name__}, not an image ({exc})") from None
    want = (height, width, 3)
    if out.shape != want:
        raise bad(f"returned an image of shape {out.shape}, expected {want} (height, width, RGB at the "
                  f"output size)")
    if not np.isfinite(out).all():          # ~2 ms a 1600x900 frame, 5-10 % of a TAA's step
        n = int(out.size - np.count_nonzero(np.isfinite(out)))
        # "produced NaN/Inf" first: the words a user greps the log for
        raise TechniqueError(f"technique {label!r} produced NaN/Inf in {n} of {out.size} values ({_source(tech)}) "
                             f"on scene {scene!r}, frame {step.frame} (step {step.k})")
    return out


def _shared(a: np.ndarray) -> np.ndarray:
    """A buffer every technique of a step reads: 64-byte aligned once (no technique's upload copies
    it again, backend.aligned), and read-only down its chain of bases, so that one technique cannot
    change another's input and the first one's finiteness check holds for the rest
    (taa_impl.sanitize)."""
    return sanitize.freeze(aligned(np.ascontiguousarray(a)))


class FrameSource:
    """Raster frames of one scene, each distinct (time, jitter, previous time) rendered once.
    `aspect`: the output's frustum, for a render below the output's size (an upscaler's).
    `lod_bias`: the filtered textures' LOD bias (raster.Rasterizer)."""

    def __init__(self, scene: ResolvedScene, width: int, height: int, buffers, aspect: float | None = None,
                 lod_bias: float = 0.0):
        self.raster = Rasterizer(scene, width, height, aspect, lod_bias=lod_bias)
        self.buffers = tuple(sorted(set(buffers) | {"color"}))
        self._memo: dict = {}
        self.rendered = 0

    @classmethod
    def for_output(cls, scene: ResolvedScene, width: int, height: int, scale: float, buffers,
                   lod_bias: float = 0.0) -> "FrameSource":
        """The frames a technique of render `scale` reads for a width x height output."""
        size = render_size(width, height, scale)
        return cls(scene, *size, buffers, None if size == (width, height) else width / height, lod_bias)

    def frame(self, t: int, jitter, prev_t: int) -> dict:
        key = frame_key(t, jitter, prev_t)
        if key not in self._memo:
            bufs = self.raster.render(t, jitter, self.buffers, prev_t=prev_t)
            self._memo[key] = {k: _shared(v) for k, v in bufs.items()}
            self.rendered += 1
        return self._memo[key]

    def forget_before(self, t: int) -> None:
        """Frames of earlier scene times are not asked for again in a moving sequence."""
        for key in [k for k in self._memo if k[0] < t]:
            del self._memo[key]

    def transient(self, t: int, jitter, prev_t: int, buffers) -> dict:
        """One frame's `buffers` (with colour), rendered now and not kept (a supersampling
        technique's sub-frame: SubFrames), or the kept frame where another step rendered it."""
        got = self._memo.get(frame_key(t, jitter, prev_t))
        if got is not None:
            return got
        self.rendered += 1
        bufs = self.raster.render(t, jitter, tuple(sorted(set(buffers) | {"color"})), prev_t=prev_t)
        return {k: _shared(v) for k, v in bufs.items()}

    def close(self):
        self.raster.close()


class SubFrames(Sequence):
    """The sub-frames of one supersampled output (Frame.samples), each rendered when it is read
    and not kept: held at once, Accumulation 128's sub-frames at 1600x900 took about 6 GB."""

    def __init__(self, src: FrameSource, t: int, jitters: list, prev_t: int, buffers):
        self.src, self.t, self.jitters, self.prev_t, self.buffers = src, t, list(jitters), prev_t, buffers

    def __len__(self) -> int:
        return len(self.jitters)

    def __getitem__(self, j):
        if isinstance(j, slice):
            return [self[i] for i in range(*j.indices(len(self)))]
        return self.src.transient(self.t, self.jitters[j], self.prev_t, self.buffers)


def drive(tech, step: Step, src: FrameSource, scene: ResolvedScene, width: int, height: int,
          display: DisplayTransform | None):
    """One step of one technique: the Frame its contract asks for, then `process`. Returns (image, stats)."""
    inp = tech.inputs
    cams = (scene.camera(step.t, width, height), scene.camera(step.prev_t, width, height)) if inp.cameras else None
    jitters = step_jitters(step, inp.sampling, inp.subframes, period=inp.jitter_period)
    one = inp.sampling != "supersample"      # else: all sub-frames of one output, rendered as read
    frame = Frame(buffers=src.frame(step.t, jitters[0], step.prev_t) if one else {},
                  samples=None if one else SubFrames(src, step.t, jitters, step.prev_t, inp.buffers),
                  jitter=jitters[0] if one else (0.0, 0.0), far=scene.desc.camera.far, reset=step.reset,
                  display=display if inp.display else None, cameras=cams,
                  output_size=(width, height) if inp.upsamples else None)
    ss_stats = {}
    if inp.masks:
        # Sparse supersampling: extra samples only where the history cannot serve the pixel.
        mask = np.ones(frame.size[::-1], bool) if step.reset else tech.invalid_mask(frame)
        ss, ss_stats = src.raster.supersample(step.t, mask, halton_offsets(inp.extra_samples))
        frame = dataclasses.replace(frame, supersampled=ss, mask=mask)
    img = tech.process(frame)
    return img, {**tech.last_stats, **ss_stats}


def run_schedule(scene: ResolvedScene, width: int, height: int, schedule: list[Step],
                 configs: list, displays: dict[int, DisplayTransform],
                 desc: str = "", progress: bool = True, emit=None) -> dict[str, dict]:
    """Run techniques over a schedule. Returns label -> {images: {frame id: image}, output_space,
    nonfinite, stats: {frame id: counters}}. With `emit(label, frame id, image)`, each judged image
    is handed to it as it is made and not kept ('images' stays empty): 100 frames of ten
    techniques at 1600x900 would hold 17 GB. Timing is not measured here (see study.engine.costs)."""
    techs = {c.label: c.make() for c in configs}
    judged = {label: {s.frame for s in judged_steps(schedule, t.inputs.sampling)} for label, t in techs.items()}
    out = {label: {"images": {}, "output_space": t.output_space, "nonfinite": 0, "stats": {}}
           for label, t in techs.items()}
    biased = has_trilinear(scene)          # else the bias changes no frame, and every size is shared
    sizes = {c.label: (render_size(width, height, techs[c.label].inputs.render_scale),
                       lod_bias(getattr(c, "lod_bias", None), techs[c.label].inputs) if biased else 0.0) for c in configs}
    srcs: dict[tuple, FrameSource] = {}     # one per render size (and bias): upscalers render below the output
    last_t = None
    try:
        for label, size in sizes.items():
            if size not in srcs:
                users = [techs[l].inputs.buffers for l in techs if sizes[l] == size]
                srcs[size] = FrameSource.for_output(scene, width, height, techs[label].inputs.render_scale,
                                                    set().union(*users), lod_bias=size[1])
        for step in tqdm(schedule, desc=desc or scene.name, unit="frame", disable=not progress,
                         leave=False, mininterval=1.0):
            if last_t is not None and step.t != last_t:
                for src in srcs.values():
                    src.forget_before(step.t)
            last_t = step.t
            for label, tech in techs.items():
                if tech.inputs.sampling != "sequence" and step.frame not in judged[label]:
                    continue
                try:
                    img, stats = drive(tech, step, srcs[sizes[label]], scene, width, height, displays.get(step.t))
                except RasterError:
                    raise
                except Exception as exc:      # the technique's own code (a user's file): named, no traceback
                    raise TechniqueError(_failure(scene.name, label, tech, step, exc)) from None
                out[label]["nonfinite"] += int(tech.last_nonfinite_count)
                shown = step.frame in judged[label] and step.keep
                img = checked_output(img, scene.name, label, tech, step, width, height)
                if shown:
                    if emit is None:
                        out[label]["images"][step.frame] = img
                    else:
                        emit(label, step.frame, img)
                    if stats:
                        out[label]["stats"][step.frame] = stats
    finally:
        for src in srcs.values():
            src.close()
    return out
