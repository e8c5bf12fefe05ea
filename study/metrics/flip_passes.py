"""FLIP's Dr.Jit passes (study.metrics.flip): one image's filtered half (colour planes and feature
magnitudes) and the per-pixel error map of two halves, frozen per layout.
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import filters as jf
from study.metrics.flip_colour import (GQF, _colour_difference, _Consts, _f32_of, _flip_quantities, _pow,
                                       _pow_type, _pow_var, _ycxcz, f32)
from backend import dr
# Frozen (dr.freeze), as SSIM's passes: the same kernels for every image of a layout, traced once
# and replayed; a new layout or constants trace again.
@dr.freeze
def _filtered(lay: jf.Layout, rgb, c: _Consts):
    """One image's half of LDR-FLIP: its filtered (Y, Cx, Cz) and its edge and point feature
    magnitudes, from linear RGB in [0, 1] (three flat arrays). The reference's half does not
    depend on the test image, so a caller judging many images against one reference keeps it."""
    planes = _ycxcz(rgb)
    dr.eval(planes)

    gY, gCx, gZ1, gZ2 = c.spatial
    g, dg, ddg = c.feature
    hf = [jf.Filter(0, gY), jf.Filter(1, gCx), jf.Filter(2, gZ1), jf.Filter(2, gZ2),
          jf.Filter(3, g), jf.Filter(3, dg), jf.Filter(3, ddg)]
    hs = jf.hpass(lay, planes, _flip_quantities, hf, "float32")
    dr.eval(hs)
    vf = [jf.Filter(0, gY), jf.Filter(1, gCx), jf.Filter(2, gZ1), jf.Filter(3, gZ2),
          jf.Filter(5, g), jf.Filter(6, g), jf.Filter(4, dg), jf.Filter(4, ddg)]
    vs = jf.vpass(lay, hs, vf, "float32")
    del hs
    dx, ddx, dy, ddy = vs[4], vs[5], vs[6], vs[7]
    out = ((vs[0], vs[1], vs[2] + vs[3]), (dr.sqrt(dx * dx + dy * dy), dr.sqrt(ddx * ddx + ddy * ddy)))
    dr.eval(out)
    return out


@dr.freeze
def _between(lay: jf.Layout, fr, feat_r, ft, feat_t, c: _Consts):
    """FLIP map of two images' filtered halves (each half computed once, however many pairs it joins)."""
    return _difference(fr, feat_r, ft, feat_t, c)


def _difference(fr, feat_r, ft, feat_t, c: _Consts):
    F64 = _pow_type()
    colour = _colour_difference(fr, ft, c, F64)
    ed = dr.abs(feat_r[0] - feat_t[0])
    pd = dr.abs(feat_r[1] - feat_t[1])
    norm = float(f32(1.0) / _f32_of(math.sqrt(2.0)))
    feature = _pow(dr.maximum(ed, pd) * norm, float(GQF), F64)
    err = _pow_var(colour, 1.0 - feature, F64)
    dr.eval(err)
    return err


def _planes(lay: jf.Layout, img: np.ndarray):
    return [lay.upload(img[..., k], "float32") for k in range(3)]
