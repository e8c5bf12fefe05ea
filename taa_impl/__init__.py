"""AA techniques, vectorised with Dr.Jit. `make(name, **overrides)` builds one by registry name.

Every technique: `params` (frozen, hashable), `inputs` (what a driver must hand it: buffers,
sampling, output space, cameras, ...; taa_impl.contract.Inputs, readable without building it as
`TECHNIQUES[name].inputs_for(params)`), `reset()`, and one entry point `process(frame) -> (H, W, 3)
float32` for a taa_impl.contract.Frame (or `process(buffers, jitter=..., far=..., ...)`).

Registry: 'noaa', 'accumulation', 'fxaa', 'taa_baseline', 'taa_improved', and named presets of the
baseline TAA's extensions (taa_impl/baseline.py), each the baseline with some TAAParams switches on:
  taa_ycocg          box='ycocg'
  taa_variance       variance_clip_gamma=1.0
  taa_catmull_rom    history_filter='catmull_rom'
  taa_tonemap_blend  tonemap_blend=True
  taa_reject         reject_depth=0.05, reject_id=True
  taa_ycocg_variance box='ycocg', variance_clip_gamma=1.0, history_filter='catmull_rom',
                     tonemap_blend=True
Also 'taa_sparse' (sparse supersampling of invalid pixels, Li, Chen, Zhang 2021; its frames carry supersampled
and mask, see taa_impl.sparse) and Ferrando's TAA (Ferrando 2018; its frames carry cameras, see taa_impl.ferrando):
  taa_ferrando_text          history_weight=0.95, clamp='current'
  taa_ferrando_code          history_weight=0.6, clamp='history'
  taa_ferrando_code_noclamp  history_weight=0.3, clamp='none'
A preset's switches are defaults: `make('taa_variance', variance_clip_gamma=1.5)` overrides one,
and `make(preset, params=...)` uses the given parameters as they are.
"""
from __future__ import annotations

from typing import Callable

from .base import (FEEDBACK_PRESETS, OUTPUT_SPACES, SAMPLING_MODES, SHARPEN_KERNELS, TAAParams,
                   Technique, build_params)
from .contract import Frame, Inputs
from .baseline import BaselineTAA
from .fxaa import ENCODED, FXAA, FXAA_QUALITY_PRESETS, FXAAParams
from .improved import ImprovedParams, ImprovedTAA
from .simple import Accumulation, AccumulationParams, NoAA, NoAAParams
from .smaa import SMAA
from .sparse import SparseParams, SparseTAA
from .ferrando import FerrandoParams, FerrandoTAA
from .taau import TAAU, TAAUParams
from .fsr2 import FSR2, FSR2Params
from .upscale import SpatialParams, SpatialUpscale, Upscaler, render_size


class Preset:
    """A registry entry: technique class `cls` with some parameter defaults, under its own name."""

    def __init__(self, name: str, cls: type, **defaults):
        self.name, self.cls, self.defaults = name, cls, dict(defaults)
        self.Params = cls.Params
        # validates the defaults; switches can add buffers
        self.inputs: Inputs = cls.inputs_for(build_params(cls.Params, None, None, **defaults))
        self.needs, self.sampling = self.inputs.buffers, self.inputs.sampling
        self.output_space, self.upsamples = self.inputs.output_space, self.inputs.upsamples

    def inputs_for(self, params=None) -> Inputs:
        """As Technique.inputs_for, with this preset's defaults when `params` is None."""
        return self.inputs if params is None else self.cls.inputs_for(params)

    def __call__(self, params=None, **overrides) -> Technique:
        kwargs = overrides if params is not None else {**self.defaults, **overrides}
        tech = self.cls(params, **kwargs)
        tech.name = self.name
        return tech

    def __repr__(self):
        return f"Preset({self.name!r}, {self.cls.__name__}, {self.defaults})"


PRESETS: dict[str, Preset] = {p.name: p for p in (
    Preset("taa_ycocg", BaselineTAA, box="ycocg"),
    Preset("taa_variance", BaselineTAA, variance_clip_gamma=1.0),
    Preset("taa_catmull_rom", BaselineTAA, history_filter="catmull_rom"),
    Preset("taa_tonemap_blend", BaselineTAA, tonemap_blend=True),
    Preset("taa_reject", BaselineTAA, reject_depth=0.05, reject_id=True),
    Preset("taa_ycocg_variance", BaselineTAA, box="ycocg", variance_clip_gamma=1.0,
           history_filter="catmull_rom", tonemap_blend=True),
    # Ferrando 2018, taa_impl/ferrando.py: the text's reading and the two shaders
    Preset("taa_ferrando_text", FerrandoTAA, history_weight=0.95, clamp="current"),
    Preset("taa_ferrando_code", FerrandoTAA, history_weight=0.6, clamp="history"),
    Preset("taa_ferrando_code_noclamp", FerrandoTAA, history_weight=0.3, clamp="none"),
    # upscaling (taa_impl.upscale): the spatial floor with a bilinear filter
    Preset("upscale_bilinear", SpatialUpscale, filter="bilinear"),
)}

TECHNIQUES: dict[str, Callable[..., Technique]] = {
    NoAA.name: NoAA,
    Accumulation.name: Accumulation,
    FXAA.name: FXAA,
    SMAA.name: SMAA,
    BaselineTAA.name: BaselineTAA,
    ImprovedTAA.name: ImprovedTAA,
    SparseTAA.name: SparseTAA,     # 'taa_sparse' (Li, Chen, Zhang 2021), taa_impl/sparse.py
    SpatialUpscale.name: SpatialUpscale,   # 'upscale_spatial': No AA at render_scale, Lanczos-2
    TAAU.name: TAAU,                       # 'taau', taa_impl/taau.py
    FSR2.name: FSR2,                       # 'fsr2', an FSR 2-class upscaler, taa_impl/fsr2.py
    **PRESETS,
}


def make(name: str, **overrides) -> Technique:
    """A fresh technique; overrides are parameter fields, `params=` (a whole params dataclass) or,
    for the TAAs, `feedback='thesis'|'inside'`."""
    try:
        factory = TECHNIQUES[name]
    except KeyError:
        raise KeyError(f"unknown technique {name!r}; known: {sorted(TECHNIQUES)}") from None
    return factory(**overrides)


__all__ = ["TECHNIQUES", "PRESETS", "Preset", "make", "Technique", "Frame", "Inputs", "TAAParams", "ImprovedParams",
           "BaselineTAA", "ImprovedTAA", "NoAA", "NoAAParams", "Accumulation", "AccumulationParams",
           "FXAA", "FXAAParams", "FXAA_QUALITY_PRESETS", "ENCODED", "FEEDBACK_PRESETS",
           "SHARPEN_KERNELS", "SAMPLING_MODES", "OUTPUT_SPACES", "SparseTAA", "SparseParams",
           "FerrandoTAA", "FerrandoParams", "TAAU", "TAAUParams", "SpatialUpscale", "SpatialParams",
           "Upscaler", "render_size", "FSR2", "FSR2Params"]
