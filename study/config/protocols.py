"""The test protocols: what a technique sees, step by step, and which outputs are judged.

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

A static scene's frames repeat with the jitter's period (16): a raster frame is identified by
`frame_key` (time, jitter, previous time), so 256 frames of history need 16 raster frames. The
engine's driver (study.engine.drive) renders each once; the estimate counts them the same way.
"""
from __future__ import annotations

from dataclasses import dataclass

from scenes import ResolvedScene
from scenes.jitter import TAA_PERIOD, halton_offset

from .defaults import GHOSTING_FRAMES, GHOSTING_WARMUP, THESIS_HISTORY


@dataclass(frozen=True)
class Step:
    t: int          # scene time (animation frame)
    k: int          # jitter index of sequence techniques
    keep: bool      # output judged
    reset: bool     # history reset before this step
    prev_t: int     # scene time of the previous step: motion vectors and previous cameras refer to it
    frame: int = -1  # id a kept output is filed under: history length (static) or scene time (ghosting)


# The figures a ghosting test prints, frame by frame (its table's best, worst and mean; the report's
# frame slider): its references are refined for these alone, and its frames are not judged in HDR.
# FLIP HDR and relMSE were half a frame's metrics (738 -> 342 ms at 1600x900) and no table printed
# them; yet FLIP HDR set hairball_rotating_lit's bounds. A static test prints every figure.
GHOSTING_FIGURES = ("mse", "psnr", "ssim", "flip_ldr")


@dataclass(frozen=True)
class Protocol:
    """A test and its parameters. `name` labels it in tables."""
    name: str
    kind: str                          # 'static' | 'ghosting'
    history: int = THESIS_HISTORY              # static: frames of history of the longest run
    checkpoints: tuple = (THESIS_HISTORY,)     # static: history lengths judged
    frames: int = GHOSTING_FRAMES              # ghosting: judged frames (capped by the scene's own)
    warmup: int = GHOSTING_WARMUP              # ghosting: unjudged frames at the first instant

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

    @property
    def figures(self) -> tuple | None:
        """The per-frame figures this test prints (None: every one); the temporal RMS besides."""
        return GHOSTING_FIGURES if self.kind == "ghosting" else None

    @property
    def hdr(self) -> bool:
        """Whether its frames are judged in linear HDR too (FLIP HDR, relMSE)."""
        return self.figures is None or "flip_hdr" in self.figures or "relmse_hdr" in self.figures

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




def frame_key(t: int, jitter, prev_t: int) -> tuple:
    """What identifies one raster frame: scene time, sub-pixel jitter and the previous time (motion
    vectors refer to it). Two steps with equal keys see the same frame."""
    return (t, round(float(jitter[0]), 9), round(float(jitter[1]), 9), prev_t)


def step_jitters(step: Step, sampling: str, subframes: int = 1, period: int = TAA_PERIOD
                 ) -> list[tuple[float, float]]:
    """The jitters of the raster frames one step of a technique of this sampling reads; `period`:
    a sequence technique's jitter phase count (an upscaler's depends on its scale)."""
    if sampling == "sequence":
        return [tuple(halton_offset(step.k, period))]
    if sampling == "centre":
        return [(0.0, 0.0)]
    if sampling == "supersample":
        return [tuple(halton_offset(j, subframes)) for j in range(subframes)]
    raise ValueError(f"unknown sampling {sampling!r}")
