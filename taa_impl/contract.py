"""The contract between a technique and the driver that runs it, as two frozen dataclasses.

`Inputs` is what a technique declares it needs, as data: its class's `contract`, refined from its
parameters by the classmethod `Technique.inputs_for(params)`, so a driver (or the planner) reads it
without building the technique -- as a render pass declares its inputs and outputs before it runs
(Falcor's `reflect()`). `Frame` is everything the driver hands over for one output frame; a
technique has one entry point, `process(frame)`. `checked` validates a frame against a contract,
once for every technique.

Sampling (`Inputs.sampling`), which raster frames the driver renders:
  'centre'      one frame with zero jitter (samples at pixel centres) per output (No AA, FXAA);
  'sequence'    frame k jittered by `scenes.jitter.halton_offset(k, jitter_period)`, one frame per
                output, history carried between them, `reset=True` at camera cuts (TAAs);
  'supersample' `subframes` sub-frames of the same scene time, sub-frame j jittered by
                `halton_offset(j, subframes)`, all handed over at once as `Frame.samples`
                (accumulation buffer / SSAA).
Output space (`Inputs.output_space`), what the returned (H, W, 3) float32 image is:
  'linear'      linear HDR Rec.709; the driver applies the display transform once, as for the
                reference;
  'display'     already display-encoded with the frame's `display` (a display.DisplayTransform:
                tone map + sRGB, floats in [0, 1]); the driver must not tone-map it again (FXAA, SMAA).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from . import sanitize

SAMPLING_MODES = ("centre", "sequence", "supersample")
OUTPUT_SPACES = ("linear", "display")


def check_scale(scale) -> float:
    """A render scale in [0.1, 1] as a float."""
    s = float(scale)
    if not (math.isfinite(s) and 0.1 <= s <= 1.0):
        raise ValueError(f"render_scale must be in [0.1, 1], got {scale!r}")
    return s


def render_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """The render resolution of an output at `scale` (FSR 2's rule: output / ratio, truncated)."""
    scale = check_scale(scale)
    return max(1, int(width * scale + 1e-6)), max(1, int(height * scale + 1e-6))


@dataclass(frozen=True)
class Inputs:
    """What a technique takes: everything a driver must hand it, declared in one place.

    Parameters
    ----------
    buffers : frozenset of str
        Raster buffers read (taa_impl.sanitize.BUFFERS names them).
    sampling : str
        One of SAMPLING_MODES (module docstring).
    output_space : str
        One of OUTPUT_SPACES; 'display' techniques are given the frame's display transform.
    cameras : bool
        Whether `Frame.cameras` (current and previous scenes.camera.CameraState) is required.
    extra_samples : int
        Supersampled samples per pixel of its mask (sparse supersampling); 0: none. With it the
        driver asks `invalid_mask(frame)` first and hands over `Frame.supersampled` and `mask`.
    subframes : int
        Jittered sub-frames per output ('supersample'), else 1.
    render_scale : float
        The raster renders `render_size(output, render_scale)` (taa_impl.upscale).
    upsamples : bool
        Renders below the output's size: `Frame.output_size` is required.
    jitter_period : int
        'sequence': frame k is jittered by halton_offset(k, jitter_period).
    """
    buffers: frozenset = frozenset({"color"})
    sampling: str = "centre"
    output_space: str = "linear"
    cameras: bool = False
    extra_samples: int = 0
    subframes: int = 1
    render_scale: float = 1.0
    upsamples: bool = False
    jitter_period: int = 16

    def __post_init__(self):
        object.__setattr__(self, "buffers", frozenset(self.buffers))
        if self.sampling not in SAMPLING_MODES:
            raise ValueError(f"sampling must be one of {SAMPLING_MODES}, got {self.sampling!r}")
        if self.output_space not in OUTPUT_SPACES:
            raise ValueError(f"output_space must be one of {OUTPUT_SPACES}, got {self.output_space!r}")

    @property
    def display(self) -> bool:
        """Whether the frame's DisplayTransform is required (output_space 'display')."""
        return self.output_space == "display"

    @property
    def masks(self) -> bool:
        """Whether the driver asks the technique's `invalid_mask` and supersamples it."""
        return self.extra_samples > 0

    def shaded_samples(self, extra_fraction: float = 0.0) -> float:
        """Samples shaded per output pixel per output frame; `extra_fraction`: share of masked pixels.
        An upscaler shades render_scale^2 per output pixel."""
        return (float(self.subframes) + self.extra_samples * extra_fraction) * self.render_scale ** 2


@dataclass(frozen=True, eq=False)
class Frame:
    """Everything a driver hands a technique for one output frame; its contract says which fields
    it must fill. `frame[name]` reads a buffer.

    Parameters
    ----------
    buffers : mapping of str to ndarray
        The raster buffers, (H, W[, C]) at the render resolution.
    far : float
        The camera's far plane (repairs a non-finite depth; normalises depth).
    jitter : (float, float)
        The sample's offset from the pixel centre, in pixels.
    reset : bool
        Forget the history first (camera cut).
    display : display.DisplayTransform, optional
        Required by output_space 'display'.
    cameras : (CameraState, CameraState), optional
        Current and previous cameras at the output size; required when the contract says so.
    output_size : (int, int), optional
        (width, height) of the output; required by an upscaler.
    samples : sequence of mappings, optional
        'supersample': every sub-frame's buffers of this output (`buffers` unused).
    supersampled : ndarray, optional
        (H, W, 3) mean of `extra_samples` jittered samples where `mask` is set (sparse supersampling).
    mask : ndarray of bool, optional
        (H, W) pixels the driver supersampled; by default the technique's own invalid_mask.
    """
    buffers: Mapping[str, Any] = field(default_factory=dict)
    far: float | None = None
    jitter: tuple = (0.0, 0.0)
    reset: bool = False
    display: Any = None
    cameras: tuple | None = None
    output_size: tuple | None = None
    samples: tuple | None = None
    supersampled: Any = None
    mask: Any = None

    def __getitem__(self, name: str):
        return self.buffers[name]

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the buffers (the render resolution)."""
        h, w = np.shape(self.buffers["color"])[:2]
        return int(w), int(h)


def as_frame(frame=None, fields: dict | None = None) -> Frame:
    """A Frame from a Frame (fields replaced), or from a mapping of buffers and the fields."""
    fields = fields or {}
    if isinstance(frame, Frame):
        return dataclasses.replace(frame, **fields) if fields else frame
    return Frame(**fields) if frame is None else Frame(buffers=frame, **fields)


def check_camera(cam, which: str, size: tuple[int, int] | None = None) -> None:
    """A scenes.camera.CameraState (`which`: its name in the error), of `size` (width, height) if given."""
    for attr in ("to_world", "yfov_deg", "width", "height"):
        if not hasattr(cam, attr):
            raise TypeError(f"{which} camera must be a scenes.camera.CameraState (no {attr!r})")
    if size is not None and (cam.width, cam.height) != size:
        raise ValueError(f"{which} camera is {cam.width}x{cam.height}, frame is {size[0]}x{size[1]}")


def checked(frame: Frame, inputs: Inputs, name: str, *, final: bool = True) -> tuple[Frame, dict]:
    """`frame` validated against `inputs` for the technique `name`: (the frame with its buffers
    repaired and its fields normalised, the non-finite pixels repaired per buffer). A missing or
    malformed input is a one-line error naming it. `final=False`: the frame of an `invalid_mask`
    pre-pass (no supersampled colour yet)."""
    far = float(frame.far) if frame.far is not None else math.nan
    if not (math.isfinite(far) and far > 0):
        raise ValueError(f"far must be finite and > 0, got {frame.far}")
    jx, jy = (float(v) for v in frame.jitter)
    if not (math.isfinite(jx) and math.isfinite(jy)):
        raise ValueError(f"jitter must be finite, got {frame.jitter!r}")
    if inputs.display and frame.display is None:
        raise ValueError(f"{name} works on the display image: pass display=DisplayTransform")
    missing = inputs.buffers - frame.buffers.keys()
    if missing:
        raise KeyError(f"{name} needs buffers {sorted(missing)}")
    w, h = frame.size
    out = (w, h)
    if inputs.upsamples:
        if frame.output_size is None:
            raise ValueError(f"{name} upsamples: pass output_size=(width, height)")
        out = tuple(int(v) for v in frame.output_size)
        rw, rh = render_size(*out, inputs.render_scale)
        if (w, h) != (rw, rh):
            raise ValueError(f"{name} at render_scale {inputs.render_scale} of {out[0]}x{out[1]} renders "
                             f"{rw}x{rh}, got a {w}x{h} frame")
    cameras = None
    if inputs.cameras:
        if frame.cameras is None:
            raise ValueError(f"{name} needs the cameras: pass cameras=(current CameraState, previous CameraState)")
        if len(frame.cameras) != 2:
            raise ValueError("cameras must be (current, previous)")
        cameras = tuple(frame.cameras)
        for cam, which in zip(cameras, ("current", "previous")):
            check_camera(cam, which, out)
    ss = mask = None
    if inputs.masks and final:
        if frame.supersampled is None:
            raise ValueError(f"{name} needs supersampled= (the (H, W, 3) mean of {inputs.extra_samples} "
                             f"jittered samples at the pixels of invalid_mask()); the driver did not provide it")
        ss = np.asarray(frame.supersampled, dtype=np.float32)
        if ss.shape != (h, w, 3):
            raise ValueError(f"supersampled has shape {ss.shape}, expected {(h, w, 3)}")
        if frame.mask is not None:
            mask = np.asarray(frame.mask, dtype=bool)
            if mask.shape != (h, w):
                raise ValueError(f"mask has shape {mask.shape}, expected {(h, w)}")
    bufs = sanitize.check_and_repair(frame.buffers, inputs.buffers, (h, w), far)
    nonfinite = bufs.pop("_nonfinite")
    return dataclasses.replace(frame, buffers=bufs, far=far, jitter=(jx, jy), reset=bool(frame.reset),
                               cameras=cameras, output_size=out, supersampled=ss, mask=mask), nonfinite


__all__ = ["Inputs", "Frame", "as_frame", "checked", "check_camera", "render_size", "check_scale", "SAMPLING_MODES",
           "OUTPUT_SPACES"]
