"""The `Technique` interface every AA technique implements, and the parameters the TAAs share.

A technique declares what it needs as data (`contract`, an `Inputs`, refined from its parameters by
`inputs_for`; taa_impl.contract), keeps its history explicitly (so a study can reset it at a camera
cut) and is a pure function of (its parameters, its history, the frame): the same inputs give the
same output bit for bit. It has one entry point, `process(frame)`, given a `Frame` (or a mapping of
buffers and the frame's fields as keywords); a subclass implements the hook `_step(b, frame)` on the
validated frame's buffers as Dr.Jit arrays. Parameters are a frozen dataclass so a study can hash
them into a cache key.
"""
from __future__ import annotations

import dataclasses
import inspect
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

import numpy as np

import backend  # noqa: F401  (selects libLLVM and the Mitsuba variant before drjit loads)
from backend import array, dr, mi

from .contract import OUTPUT_SPACES, SAMPLING_MODES, Frame, Inputs, as_frame, checked

# Feedback presets (k_min, k_max) of the luminance feedback (Oliveros 2018, §3.6.3).
FEEDBACK_PRESETS: dict[str, tuple[float, float]] = {
    "thesis": (0.925, 0.979),  # the thesis author's implementation
    "inside": (0.88, 0.97),    # INSIDE (Pedersen 2016)
}

# Sharpen kernels (Xu 2016; Oliveros 2018, §3.6.5 and §4.3.5). Both are [[0,-w,0],[-w,1+4w,-w],[0,-w,0]]; we apply them as
# out = c + w * sum(c - n) over the 4 cross neighbours n, which is the same sum but keeps a constant
# image exactly constant (5c - 4c is not exact in float32, c + 0 is).
SHARPEN_KERNELS: dict[str, tuple[tuple[float, ...], ...]] = {
    "xu": ((0, -1, 0), (-1, 5, -1), (0, -1, 0)),                      # Xu 2016, "not normalised"
    "normalised": ((0, -.25, 0), (-.25, 2, -.25), (0, -.25, 0)),     # thesis eq. 4.13
    "none": ((0, 0, 0), (0, 1, 0), (0, 0, 0)),
}


def sharpen_weight(name) -> float:
    """The w of a cross-shaped, unit-sum kernel [[0,-w,0],[-w,1+4w,-w],[0,-w,0]]: a kernel's name, or
    w itself (a strength between none's 0, the normalised kernel's 0.25 and Xu's 1)."""
    if not isinstance(name, str):
        return float(name)
    k = SHARPEN_KERNELS[name]
    w = -float(k[0][1])
    assert k[1][1] == 1 + 4 * w and k[0][0] == k[0][2] == k[2][0] == k[2][2] == 0
    return w


def check_sharpen(sharpen) -> None:
    """A kernel's name or a strength w in [0, 4] (w > 4 would weigh the centre above 17)."""
    if isinstance(sharpen, bool) or not isinstance(sharpen, (str, int, float)):
        raise ValueError(f"sharpen must be one of {sorted(SHARPEN_KERNELS)} or a strength in [0, 4], got {sharpen!r}")
    if isinstance(sharpen, str):
        if sharpen not in SHARPEN_KERNELS:
            raise ValueError(f"sharpen must be one of {sorted(SHARPEN_KERNELS)} or a strength in [0, 4], got {sharpen!r}")
    elif not (math.isfinite(sharpen) and 0 <= sharpen <= 4):
        raise ValueError(f"sharpen strength must be in [0, 4] (0 none, 0.25 normalised, 1 Xu), got {sharpen!r}")


BOX_SPACES = ("minmax", "ycocg")
HISTORY_FILTERS = ("bilinear", "catmull_rom", "catmull_rom_5")


@dataclass(frozen=True)
class TAAParams:
    """Parameters of the baseline TAA (Oliveros 2018, §3.6). Defaults: thesis feedback preset, Xu's sharpen."""
    k_min: float = FEEDBACK_PRESETS["thesis"][0]
    k_max: float = FEEDBACK_PRESETS["thesis"][1]
    feedback_luma: tuple[float, float, float] = (0.25, 0.5, 0.25)  # INSIDE's (YCoCg Y) weights
    feedback_floor: float = 0.2      # lower bound of the luminance denominator (INSIDE)
    clip_eps: float = 1e-8           # INSIDE's FLT_EPS added to the clip box half-size (absolute)
    clip_tol: float = 1e-4           # plus this times the box's magnitude (kernels.clip_toward_centre);
    #                                  0 = INSIDE's clip, whose decision float32 rounding makes
    sharpen: str | float = "xu"               # a SHARPEN_KERNELS name or the cross kernel's w
    # Extensions beyond the thesis's TAA (published techniques, named below); every default is "off" = the baseline above.
    box: str = "minmax"                       # 'minmax': RGB box; 'ycocg': box and clip in YCoCg (Karis 2014)
    variance_clip_gamma: float | None = None  # Salvi 2016: box = mu -/+ gamma*sigma over the 3x3
    variance_intersect: bool = False          # True: intersect the variance box with the min/max box
    history_filter: str = "bilinear"          # 'bilinear' | 'catmull_rom' (exact 4x4 = the 9-tap form)
    #                                           | 'catmull_rom_5' (5-tap, corners dropped, renormalised)
    tonemap_blend: bool = False               # Karis: blend in c / (1 + luma(c)) space, invert after
    tonemap_luma: tuple[float, float, float] = (0.2126, 0.7152, 0.0722)   # luma of that tone map
    reject_depth: float | None = None         # reject history if stored depth differs by > this (relative)
    reject_id: bool = False                   # reject history if the stored object ID differs

    def __post_init__(self):
        if not (0.0 <= self.k_min <= self.k_max <= 1.0):
            raise ValueError(f"need 0 <= k_min <= k_max <= 1, got {self.k_min}, {self.k_max}")
        # eps > 0 keeps v/e finite for a zero-size box; floor > 0 keeps 0/0 out of the feedback.
        if not self.clip_eps > 0:
            raise ValueError("clip_eps must be > 0 (a zero-size box would divide by zero)")
        if not (math.isfinite(self.clip_tol) and 0 <= self.clip_tol < 1):
            raise ValueError(f"clip_tol must be in [0, 1), got {self.clip_tol}")
        if not self.feedback_floor > 0:
            raise ValueError("feedback_floor must be > 0")
        if len(self.feedback_luma) != 3:
            raise ValueError("feedback_luma needs 3 weights")
        object.__setattr__(self, "feedback_luma", tuple(float(v) for v in self.feedback_luma))
        check_sharpen(self.sharpen)
        if not isinstance(self.sharpen, str):       # 1 and 1.0 are one technique (and one run key)
            object.__setattr__(self, "sharpen", float(self.sharpen))
        if self.box not in BOX_SPACES:
            raise ValueError(f"box must be one of {BOX_SPACES}, got {self.box!r}")
        if self.variance_clip_gamma is not None:
            g = float(self.variance_clip_gamma)
            if not (math.isfinite(g) and g >= 0):
                raise ValueError(f"variance_clip_gamma must be None or a finite value >= 0, got {g}")
            object.__setattr__(self, "variance_clip_gamma", g)
        if self.history_filter not in HISTORY_FILTERS:
            raise ValueError(f"history_filter must be one of {HISTORY_FILTERS}, got {self.history_filter!r}")
        if len(self.tonemap_luma) != 3:
            raise ValueError("tonemap_luma needs 3 weights")
        object.__setattr__(self, "tonemap_luma", tuple(float(v) for v in self.tonemap_luma))
        if self.reject_depth is not None:
            r = float(self.reject_depth)
            if not (math.isfinite(r) and r >= 0):
                raise ValueError(f"reject_depth must be None or a finite value >= 0, got {r}")
            object.__setattr__(self, "reject_depth", r)
        for flag in ("variance_intersect", "tonemap_blend", "reject_id"):
            object.__setattr__(self, flag, bool(getattr(self, flag)))

    @property
    def rejects(self) -> bool:
        """Whether any history rejection test is on."""
        return self.reject_depth is not None or self.reject_id


def build_params(cls: type, params: Any = None, feedback: str | None = None, **overrides) -> Any:
    """Defaults of `cls`, then a feedback preset, then explicit overrides (a preset and an explicit
    k_min/k_max together are ambiguous and refused)."""
    p = params if params is not None else cls()
    if feedback is not None:
        if not hasattr(p, "k_min"):
            raise ValueError(f"a feedback preset applies to TAAs only, not to {cls.__name__}")
        if feedback not in FEEDBACK_PRESETS:
            raise ValueError(f"feedback preset must be one of {sorted(FEEDBACK_PRESETS)}")
        if "k_min" in overrides or "k_max" in overrides:
            raise ValueError("give either a feedback preset or k_min/k_max, not both")
        kmin, kmax = FEEDBACK_PRESETS[feedback]
        p = dataclasses.replace(p, k_min=kmin, k_max=kmax)
    if dataclasses.is_dataclass(p):
        known = [f.name for f in dataclasses.fields(p)]
        unknown = sorted(set(overrides) - set(known))
        if unknown:
            raise TypeError(f"unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} "
                             f"of {cls.__name__}; its parameters: {', '.join(known)}")
    return dataclasses.replace(p, **overrides) if overrides else p


class _Declared:
    """A field of the technique's `Inputs`, read on the class (its default parameters' inputs) or on
    an instance (its own): `FXAA.output_space`, `tech.needs`."""

    def __init__(self, field: str):
        self.field = field

    def __get__(self, obj, cls):
        return getattr(cls.inputs_for() if obj is None else obj.inputs, self.field)


# The older spelling of a declaration, still read from a researcher's class: attribute -> Inputs field.
_LEGACY = {"needs": "buffers", "sampling": "sampling", "output_space": "output_space", "upsamples": "upsamples"}


class Technique:
    """Base class: the contract, the one entry point `process`, validation and repair of the inputs
    (taa_impl.contract.checked), NumPy <-> Dr.Jit, history reset.

    A subclass declares `name`, `Params`, `contract` (an `Inputs`; `inputs_for` when it depends on
    the parameters) and implements `_clear_history` and `_step(b, frame)`: `b` the frame's buffers as
    flat Dr.Jit arrays, `frame` the validated `Frame`; it returns the output colour (mi.Color3f at the
    output size) and updates the history. `needs`, `sampling`, `output_space` and `upsamples` read
    the contract."""

    name: ClassVar[str] = "technique"
    Params: ClassVar[type] = TAAParams
    contract: ClassVar[Inputs] = Inputs()
    needs = _Declared("buffers")
    sampling = _Declared("sampling")
    output_space = _Declared("output_space")
    upsamples = _Declared("upsamples")

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        legacy = {f: cls.__dict__[a] for a, f in _LEGACY.items() if a in cls.__dict__}
        if legacy:      # `needs = ...` and the like: folded into the class's contract
            for a in _LEGACY:
                if a in cls.__dict__:
                    delattr(cls, a)
            try:
                cls.contract = dataclasses.replace(cls.contract, **legacy)
            except ValueError as exc:
                raise ValueError(f"technique class {cls.__name__}: {exc}") from None
        step = cls.__dict__.get("_step")
        if step is not None and len(inspect.signature(step).parameters) == 5:
            def _step(self, b, frame, _legacy=step):    # the older hook _step(b, width, height, far)
                return _legacy(self, b, *frame.size, frame.far)
            cls._step = _step

    @classmethod
    def inputs_for(cls, params: Any = None) -> Inputs:
        """What a driver must hand this technique with `params` (default: its Params' defaults),
        without building it. The class's `contract` unless a subclass derives it from the params."""
        return cls.contract

    def __init__(self, params=None, *, feedback: str | None = None, **overrides):
        self.params = build_params(self.Params, params, feedback, **overrides)
        self._inputs = type(self).inputs_for(self.params)
        self.last_nonfinite_count = 0          # non-finite input pixels repaired in the last frame
        self.last_nonfinite: dict[str, int] = {}
        self.last_jitter: tuple[float, float] | None = None
        self.last_stats: dict = {}             # the last frame's counters, recorded by the driver
        self._shape: tuple[int, int] | None = None
        self.reset()

    @property
    def inputs(self) -> Inputs:
        """What a driver must hand this technique (its parameters' `inputs_for`)."""
        return self._inputs

    def __repr__(self):
        return f"{type(self).__name__}({self.params})"

    # -- history -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget all history (camera cut, first frame)."""
        self._clear_history()

    def _clear_history(self) -> None:
        raise NotImplementedError

    # -- per frame -----------------------------------------------------------------------------
    def process(self, frame: Frame | Mapping | None = None, /, **fields) -> np.ndarray:
        """One output frame in, the displayed (H, W, 3) float32 image out; updates the history.

        Parameters
        ----------
        frame : Frame or mapping of str to ndarray
            A `Frame`, or its buffers with the other fields of `Frame` as keywords
            (`process(buffers, jitter=(jx, jy), far=100.0, reset=True)`).
        **fields
            Fields of `Frame` (replacing a given Frame's).

        Returns
        -------
        ndarray
            (H, W, 3) float32 at the output size, in the contract's output space. A frame with
            `samples` (sampling 'supersample') restarts the history and steps every sub-frame in
            turn; its output is the last step's.
        """
        frame = as_frame(frame, fields)
        if frame.samples is None:
            return self._frame(frame)
        # read one sub-frame at a time: the driver's are rendered as they are read (SubFrames)
        self.reset()
        total, out, first = 0, None, None
        for bufs in frame.samples:
            shape = np.shape(bufs["color"])[:2]
            first = shape if first is None else first
            if shape != first:
                self.reset()
                raise ValueError(f"sub-frames of one output must share a resolution, got {sorted({first, shape})}")
            out = self._frame(dataclasses.replace(frame, buffers=bufs, samples=None, reset=False))
            total += self.last_nonfinite_count
        if first is None:
            raise ValueError(f"{self.name} needs at least one sub-frame in samples")
        self.last_nonfinite_count = total
        return out

    def _frame(self, frame: Frame) -> np.ndarray:
        frame, self.last_nonfinite = checked(frame, self.inputs, self.name)
        self.last_nonfinite_count = sum(self.last_nonfinite.values())
        self.last_jitter = frame.jitter  # informational: the sample is used where it was taken
        w, h = frame.output_size
        if self._shape != (h, w):  # a change of the output's size invalidates the history
            self.reset()
            self._shape = (h, w)
        if frame.reset:
            self.reset()
        out = self._step(to_drjit(self._prepare(frame)), frame)
        return from_drjit_color(out, h, w)

    def invalid_mask(self, frame: Frame | Mapping | None = None, /, **fields) -> np.ndarray | None:
        """(H, W) bool: this frame's pixels that need the supersampled colour (a contract with
        `extra_samples`), computed without changing any state; None for a technique without."""
        return None

    def _prepare(self, frame: Frame) -> dict[str, np.ndarray]:
        """NumPy-side preparation of the (validated, repaired) buffers; the default is none."""
        return frame.buffers

    def _step(self, b: dict, frame: Frame):
        """One frame: `b` the validated buffers as flat Dr.Jit arrays (y * W + x), `frame` the
        validated Frame. Returns the output colour (mi.Color3f at the output size); updates the history."""
        raise NotImplementedError


def to_drjit(bufs: dict[str, np.ndarray]) -> dict:
    """NumPy (H, W, ...) arrays to flat Dr.Jit arrays indexed y*W + x."""
    out = {}
    for key, a in bufs.items():
        if key in ("color", "albedo"):
            out[key] = dr.unravel(mi.Color3f, array(mi.Float, a))
        elif key == "motion":
            out[key] = dr.unravel(mi.Vector2f, array(mi.Float, a))
        elif key == "object_id":
            out[key] = array(mi.Int32, a)
        else:
            out[key] = array(mi.Float, a)
    return out


def from_drjit_color(c, h: int, w: int) -> np.ndarray:
    return np.asarray(dr.ravel(c), dtype=np.float32).reshape(h, w, 3).copy()


def from_drjit_scalar(f, h: int, w: int) -> np.ndarray:
    return np.asarray(f, dtype=np.float32).reshape(h, w).copy()


def terms_to_numpy(terms: dict, h: int, w: int) -> dict[str, np.ndarray]:
    """A technique's per-pixel intermediates (Dr.Jit colours, vectors, scalars) as NumPy (H, W[, C])."""
    if not terms:
        return {}
    dr.eval(*terms.values())
    out = {}
    for key, v in terms.items():
        n = {mi.Color3f: 3, mi.Vector2f: 2}.get(type(v), 1)
        a = np.asarray(dr.ravel(v) if n > 1 else mi.Float(v), np.float32)
        out[key] = a.reshape((h, w, n) if n > 1 else (h, w)).copy()
    return out


class DisplayImageTechnique(Technique):
    """A single-image post-process on the display image (FXAA, SMAA): the driver renders the
    unjittered frame, the colour is display-encoded here, and `kernel(grid, rgb, params)` returns
    the output and its per-pixel intermediates."""
    contract = Inputs(buffers={"color"}, sampling="centre", output_space="display")

    @staticmethod
    def kernel(grid, rgb, params):
        raise NotImplementedError

    def _clear_history(self) -> None:
        self._grid = None
        self._terms: dict = {}

    def _prepare(self, frame):
        bufs = dict(frame.buffers)
        bufs["color"] = np.ascontiguousarray(frame.display.encode(bufs["color"]), dtype=np.float32)
        return bufs

    def _step(self, b: dict, frame):
        from . import kernels as K
        w, h = frame.size
        if self._grid is None or (self._grid.w, self._grid.h) != (w, h):
            self._grid = K.Grid(w, h)
        out, self._terms = type(self).kernel(self._grid, b["color"], self.params)
        return out

    def debug_terms(self) -> dict[str, np.ndarray]:
        """Per-pixel intermediates of the last frame as (H, W) float32 arrays."""
        h, w = self._shape
        return {k: np.asarray(v, np.float32).reshape(h, w).copy() for k, v in self._terms.items()}
