"""The two reference points of the study (Oliveros 2018, §3.7): No AA and the accumulation buffer.

- No AA (`noaa`): the single sample at each pixel centre, returned as is (sampling 'centre').
- Accumulation buffer / SSAA (`accumulation`, Haeberli & Akeley 1990): the mean of N jittered
  sub-frames of the same scene time (sampling 'supersample'); the thesis's ground truth is N = 128.
  Sums are kept in float64 and divided once: the mean of N equal float32 values is that value
  exactly, and for N <= 2**29 samples no precision is lost to the running sum.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

from .base import Frame, Inputs, Technique, from_drjit_color


@dataclass(frozen=True)
class NoAAParams:
    """No AA has no parameters."""


class NoAA(Technique):
    name = "noaa"
    Params = NoAAParams
    contract = Inputs(buffers={"color"}, sampling="centre")

    def _clear_history(self) -> None:
        pass

    def _step(self, b: dict, frame: Frame):
        return b["color"]


@dataclass(frozen=True)
class AccumulationParams:
    samples: int = 128   # sub-frames per output (the thesis's ground truth: 128); any N >= 1

    def __post_init__(self):
        if isinstance(self.samples, bool) or int(self.samples) != self.samples or self.samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        object.__setattr__(self, "samples", int(self.samples))


class Accumulation(Technique):
    """Mean of jittered sub-frames. `process(Frame(samples=frames, ...))` gives the mean of exactly
    those frames; a frame of one `buffers` adds it to a running mean and returns that (until
    `reset()`, a `reset=True` frame or a resolution change, which start a new mean). `count` is the
    number of frames in the current mean. The driver renders sub-frame j with halton_offset(j, samples)."""

    name = "accumulation"
    Params = AccumulationParams
    contract = Inputs(buffers={"color"}, sampling="supersample")

    @classmethod
    def inputs_for(cls, params=None) -> Inputs:
        n = (params if params is not None else cls.Params()).samples
        return dataclasses.replace(cls.contract, subframes=n)

    def _clear_history(self) -> None:
        self._sum = None   # mi.Color3d
        self.count = 0

    def _step(self, b: dict, frame: Frame):
        c = mi.Color3d(b["color"])
        self._sum = c if self._sum is None else self._sum + c
        dr.eval(self._sum)
        self.count += 1
        return mi.Color3f(self._sum * self._inv_count())

    def _inv_count(self):
        """1 / count, opaque: Dr.Jit computes `x / literal n` as x times 1/n (double here), so this
        is the same mean, with one kernel for every count instead of one per count."""
        return dr.opaque(mi.Float64, 1.0 / self.count)

    @property
    def mean(self) -> np.ndarray | None:
        """The current running mean as NumPy, or None after a reset."""
        if self._sum is None:
            return None
        return from_drjit_color(mi.Color3f(self._sum * self._inv_count()), *self._shape)


__all__ = ["NoAA", "NoAAParams", "Accumulation", "AccumulationParams"]
