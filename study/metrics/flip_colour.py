"""FLIP's constants and colour pipeline (study.metrics.flip): the CSF and feature filters for a
viewing distance in pixels per degree, sRGB -> linear -> YCxCz, CIELab with the Hunt adjustment, the
HyAB colour difference and its remap, all in float32 as flip-evaluator 1.7's C++ path (NVlabs/flip
FLIP.h) computes them.

References
----------
P. Andersson, J. Nilsson, T. Akenine-Moller, M. Oskarsson, K. Astrom, M. D. Fairchild, "FLIP: A
Difference Evaluator for Alternating Images", Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020.
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import checks
from study.metrics import filters as jf
from backend import dr

f32 = np.float32
PI = f32(3.14159265358979)
GQC, GPC, GPT, GW, GQF = f32(0.7), f32(0.4), f32(0.95), f32(0.082), f32(0.5)
ILLUMINANT = (f32(0.950428545), f32(1.0), f32(1.088900371))
INV_ILLUMINANT = (f32(1.052156925), f32(1.0), f32(0.918357670))
# Gaussian constants (a1, b1, a2, b2) per YCxCz channel.
A1 = (f32(1.0), f32(1.0), f32(34.1))
B1 = (f32(0.0047), f32(0.0053), f32(0.04))
A2 = (f32(0.0), f32(0.0), f32(13.5))
B2 = (f32(1.0e-5), f32(1.0e-5), f32(0.025))
# The C++ writes these as float quotients (10135552.0f / 24577794.0f): rounded operands, float division.
RGB2XYZ = tuple(tuple(float(f32(n) / f32(d)) for n, d in row) for row in (
    ((10135552, 24577794), (8788810, 24577794), (4435075, 24577794)),
    ((2613072, 12288897), (8788810, 12288897), (887015, 12288897)),
    ((1425312, 73733382), (8788810, 73733382), (70074185, 73733382))))
XYZ2RGB = ((3.241003275, -1.537398934, -0.498615861),
           (-0.969224334, 1.875930071, 0.041554224),
           (0.055639423, -0.204011202, 1.057148933))
XYZ2RGB = tuple(tuple(float(f32(v)) for v in row) for row in XYZ2RGB)
# ACES (with FLIP's 0.6 pre-exposure cancellation): (x^2 c0 + x c1 + c2) / (x^2 c3 + x c4 + c5).
ACES = (f32(0.6) * f32(0.6) * f32(2.51), f32(0.6) * f32(0.03), f32(0.0),
        f32(0.6) * f32(0.6) * f32(2.43), f32(0.6) * f32(0.59), f32(0.14))


def _f32_of(x: float) -> f32:
    """A float64 evaluation rounded to float32: what a correctly rounded libm float call returns."""
    return f32(x)


def default_ppd() -> f32:
    """flip-evaluator's default pixels per degree: 0.7 m from a 0.7 m wide, 3840 pixel display.

    Returns
    -------
    numpy.float32
        About 67.02, computed in float32 as the C++ does.
    """
    return f32(0.7) * (f32(3840.0) / f32(0.7)) * (PI / f32(180.0))


def spatial_radius(ppd: f32) -> int:
    """Radius of the colour pipeline's CSF filters (setSpatialFilters).

    Parameters
    ----------
    ppd : numpy.float32
        Pixels per degree of visual angle.

    Returns
    -------
    int
        10 at the default ppd (a 21-tap filter).
    """
    pi_sq = PI * PI
    b = max(B1 + B2)
    return int(math.ceil(f32(3.0) * _f32_of(math.sqrt(b / (f32(2.0) * pi_sq))) * ppd))


def _gauss(x2: f32, a: f32, b: f32, sqrt_amp: bool) -> f32:
    pi_sq = PI * PI
    amp = a * _f32_of(math.sqrt(PI / b))
    if sqrt_amp:
        amp = _f32_of(math.sqrt(amp))
    return amp * _f32_of(math.exp(-pi_sq * x2 / b))


def spatial_filters(ppd: f32):
    """The colour pipeline's 1-D CSF filters, normalised as setSpatialFilters does.

    Parameters
    ----------
    ppd : numpy.float32
        Pixels per degree of visual angle.

    Returns
    -------
    tuple of tuple of float
        (gY, gCx, gCz1, gCz2), float32 values: Y and Cx one Gaussian each, Cz a sum of two applied
        as two separable Gaussians of square-rooted amplitude (Andersson et al. 2020, sec. 4.1).
    """
    r = spatial_radius(ppd)
    dx = f32(1.0) / ppd
    gy, gcx, gz1, gz2 = [], [], [], []
    for x in range(2 * r + 1):
        ix = f32(x - r) * dx
        ix2 = ix * ix
        gy.append(_gauss(ix2, A1[0], B1[0], False))
        gcx.append(_gauss(ix2, A1[1], B1[1], False))
        gz1.append(_gauss(ix2, A1[2], B1[2], True))
        gz2.append(_gauss(ix2, A2[2], B2[2], True))

    def fsum(v):
        s = f32(0.0)
        for t in v:
            s = s + t
        return s
    ny, ncx = f32(1.0) / fsum(gy), f32(1.0) / fsum(gcx)
    s1, s2 = fsum(gz1), fsum(gz2)
    nz = f32(1.0) / _f32_of(math.sqrt(s1 * s1 + s2 * s2))
    out = ([t * ny for t in gy], [t * ncx for t in gcx], [t * nz for t in gz1], [t * nz for t in gz2])
    return tuple(tuple(float(t) for t in v) for v in out)


def feature_filters(ppd: f32):
    """The feature pipeline's Gaussian and its first and second derivatives, as setFeatureFilter.

    Parameters
    ----------
    ppd : numpy.float32
        Pixels per degree of visual angle.

    Returns
    -------
    tuple of tuple of float
        (g, dg, ddg), float32 values: g sums to 1, dg and ddg have positive and negative parts
        summing to 1 and -1 each (Andersson et al. 2020, sec. 4.2).
    """
    sd = f32(0.5) * GW * ppd
    r = int(math.ceil(f32(3.0) * sd))
    g, dg, ddg = [], [], []
    gs, dpos, dneg, ddpos, ddneg = (f32(0.0),) * 5
    for x in range(2 * r + 1):
        xx = f32(x - r)
        gv = _f32_of(math.exp(-(xx * xx) / (f32(2.0) * sd * sd)))
        gs = gs + gv
        d = -xx * gv
        if d > 0:
            dpos = dpos + d
        else:
            dneg = dneg - d
        dd = (xx * xx / (sd * sd) - f32(1.0)) * gv
        if dd > 0:
            ddpos = ddpos + dd
        else:
            ddneg = ddneg - dd
        g.append(gv)
        dg.append(d)
        ddg.append(dd)
    g = [t / gs for t in g]
    dg = [t / (dpos if t > 0 else dneg) for t in dg]
    ddg = [t / (ddpos if t > 0 else ddneg) for t in ddg]
    return tuple(tuple(float(t) for t in v) for v in (g, dg, ddg))


def _lab_hunt_host(rgb):
    """Host float32 CIELab + Hunt of one linear RGB colour (for cmax)."""
    xyz = [f32(0.0)] * 3
    for i in range(3):
        acc = f32(RGB2XYZ[i][0]) * rgb[0]
        acc = acc + f32(RGB2XYZ[i][1]) * rgb[1]
        xyz[i] = acc + f32(RGB2XYZ[i][2]) * rgb[2]
    delta = f32(6.0) / f32(29.0)
    dsq = delta * delta
    dcube = delta * dsq
    factor = f32(1.0) / (f32(3.0) * dsq)
    term = f32(4.0) / f32(29.0)
    v = [xyz[i] * INV_ILLUMINANT[i] for i in range(3)]
    v = [_f32_of(float(t) ** float(f32(1.0) / f32(3.0))) if t > dcube else factor * t + term for t in v]
    L = f32(116.0) * v[1] - f32(16.0)
    a = f32(500.0) * (v[0] - v[1])
    b = f32(200.0) * (v[1] - v[2])
    return L, f32(0.01) * L * a, f32(0.01) * L * b


def max_distance() -> f32:
    """FLIP's largest colour distance (green against blue, HyAB in Hunt-adjusted CIELab, ^0.7).

    Returns
    -------
    numpy.float32
        c_max of Andersson et al. 2020, eq. 4, in float32 as the C++ computes it.
    """
    g = _lab_hunt_host((f32(0), f32(1), f32(0)))
    b = _lab_hunt_host((f32(0), f32(0), f32(1)))
    hy = abs(g[0] - b[0]) + _f32_of(math.sqrt((g[1] - b[1]) * (g[1] - b[1]) + (g[2] - b[2]) * (g[2] - b[2])))
    return _f32_of(float(hy) ** float(GQC))


# Precision of the pow/cbrt evaluations. float64 rounds like a correctly rounded powf and agrees
# a little closer (map max |diff| 2.5e-6 against 3.6e-6 on 64x48 pairs), float32 is ~25% faster.
POW_PRECISION = "float32"


def _pow_type():
    J = jf.jit()
    return J.Float64 if POW_PRECISION == "float64" else J.Float


def _pow(x, y: float, F64):
    """x^y for x >= 0 as a float32 result, evaluated in F64 (see POW_PRECISION)."""
    xd = F64(x)
    r = dr.exp2(dr.log2(xd) * y) if y != 0.5 else dr.sqrt(xd)
    return type(x)(dr.select(xd > 0, r, 0.0))


def _pow_var(x, y, F64):
    """x^y for x >= 0 and a per-pixel exponent y, float32 result, C's pow at x = 0."""
    xd, yd = F64(x), F64(y)
    r = dr.exp2(dr.log2(xd) * yd)
    r = dr.select(xd > 0, r, dr.select(yd == 0, 1.0, dr.select(yd > 0, 0.0, math.inf)))
    return type(x)(r)


def _srgb_to_linear(c, F64):
    lin_hi = _pow((c + f32(0.055)) / f32(1.055), float(f32(2.4)), F64)
    return dr.select(c <= f32(0.04045), c / f32(12.92), lin_hi)


def _matvec(m, v):
    out = []
    for row in m:
        acc = v[0] * row[0]
        acc = acc + v[1] * row[1]
        out.append(acc + v[2] * row[2])
    return out


def _ycxcz(rgb):
    x, y, z = _matvec(RGB2XYZ, rgb)
    x, y, z = x * float(INV_ILLUMINANT[0]), y * float(INV_ILLUMINANT[1]), z * float(INV_ILLUMINANT[2])
    return [y * 116.0 - 16.0, (x - y) * 500.0, (y - z) * 200.0]


class _Consts:
    def __init__(self, ppd: f32):
        self.ppd = ppd
        self.spatial = spatial_filters(ppd)
        self.feature = feature_filters(ppd)
        self.cmax = max_distance()
        self.pccmax = GPC * self.cmax


_CONSTS: dict[float, _Consts] = {}


def consts(ppd: f32 | None = None) -> _Consts:
    """FLIP's filters and constants for a viewing condition, made once per ppd and kept.

    Parameters
    ----------
    ppd : float, optional
        Pixels per degree of visual angle (`default_ppd` when omitted).

    Returns
    -------
    _Consts
        With ``ppd``, ``spatial`` (`spatial_filters`), ``feature`` (`feature_filters`), ``cmax``
        (`max_distance`) and ``pccmax``.

    Raises
    ------
    ValueError
        If `ppd` is not a finite number > 0.
    """
    ppd = default_ppd() if ppd is None else f32(checks.positive("FLIP", "ppd", ppd))
    if float(ppd) not in _CONSTS:
        _CONSTS[float(ppd)] = _Consts(ppd)
    return _CONSTS[float(ppd)]


def _lab_hunt(xyz, F64):
    delta = f32(6.0) / f32(29.0)
    dsq = delta * delta
    dcube = float(delta * dsq)
    factor = float(f32(1.0) / (f32(3.0) * dsq))
    term = float(f32(4.0) / f32(29.0))
    third = float(f32(1.0) / f32(3.0))
    v = [xyz[i] * float(INV_ILLUMINANT[i]) for i in range(3)]
    v = [dr.select(t > dcube, _pow(t, third, F64), t * factor + term) for t in v]
    L = v[1] * 116.0 - 16.0
    a = (v[0] - v[1]) * 500.0
    b = (v[1] - v[2]) * 200.0
    hl = L * 0.01
    return L, hl * a, hl * b


def _colour_difference(fr, ft, c: _Consts, F64):
    """fr, ft: filtered (Y, Cx, Cz) of reference and test -> remapped colour difference."""
    labs = []
    for y, cx, cz in (fr, ft):
        yy = (y + 16.0) / 116.0
        X = (yy + cx / 500.0) * float(ILLUMINANT[0])
        Y = yy * float(ILLUMINANT[1])
        Z = (yy - cz / 200.0) * float(ILLUMINANT[2])
        rgb = [dr.clip(t, 0.0, 1.0) for t in _matvec(XYZ2RGB, [X, Y, Z])]
        labs.append(_lab_hunt(_matvec(RGB2XYZ, rgb), F64))
    (l1, a1, b1), (l2, a2, b2) = labs
    da, db = a1 - a2, b1 - b2
    hyab = dr.abs(l1 - l2) + dr.sqrt(da * da + db * db)
    cd = _pow(hyab, float(GQC), F64)
    low = cd * float(GPT / c.pccmax)
    high = ((cd - float(c.pccmax)) / float(c.cmax - c.pccmax)) * float(f32(1.0) - GPT) + float(GPT)
    return dr.select(cd < float(c.pccmax), low, high)


_ONE116, _SIX116 = float(f32(1.0) / f32(116.0)), float(f32(16.0) / f32(116.0))


def _flip_quantities(v):
    return [v[0], v[1], v[2], v[0] * _ONE116 + _SIX116]
