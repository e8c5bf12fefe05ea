"""SMAA's two lookup functions, computed here from their definitions (nothing is copied from the
reference's precomputed areaTex / searchTex).

Search function (what searchTex tabulates)
-------------------------------------------
The orthogonal searches read the edges texture with ONE bilinear fetch per two pixels, at an offset
of (-0.25, -0.125) px (left search; mirrored for the others) from a texel corner, so each fetch
mixes four texels with weights 0.875 * (0.75, 0.25) across the line and 0.125 * (0.75, 0.25) on the
row beyond it. In units of 1/32 these are 21, 7, 3 and 1: every subset of the four bits has a
distinct sum, so round(32 * value) (0..32) identifies exactly which of the four edges are on. For the
channel along the line (the edge we follow) and the crossing channel (edges perpendicular to it)
this gives 8 bits per fetch. `search_delta_table()` enumerates all 2^8 combinations and stores, per
(round(32 * crossing), round(32 * along)), how many of the two fetched pixels still belong to the
line (0, 1 or 2):
  near = the fetched pixel nearer the current one, far = the other;
  towards -along (left / up): +1 if near carries the edge; +1 more if far carries it too and no
      crossing edge separates near and far (a crossing edge at far's own outer side ends the line
      *at* far, so it does not stop it);
  towards +along (right / down): +1 if near carries the edge and no crossing edge lies between it
      and the previous pixel; +1 more if far carries it and no crossing edge lies between near and far.
This is the "disambiguate the length added by the last step" the shader comments describe; the
shader's `3.25 - (255/127) * searchTex` becomes `3.25 - delta` here (the 255/127 only undoes the
texture's 8-bit packing of 0, 1, 2).

Area functions (what areaTex tabulates)
---------------------------------------
Orthogonal (MLAA revectorisation, Jimenez et al. 2011/2012): an edge segment of d = dl + dr + 1
pixels, the current pixel covering [dl, dl + 1] along it. At each end a crossing edge on one side
means the true edge bends to that side there: the revectorised line goes from the middle of that
crossing edge, height +-0.5 at the segment's end, to height 0 at the segment's middle d/2
(L shapes: one end; Z / U shapes: both ends, two half-lines meeting at d/2). An end without a
crossing edge, or with crossing edges on both sides (a T / + junction: no stair step to
revectorise), has height 0. The weights are the areas between this line and the edge inside the
current pixel's interval: on the side where the line is (above: the pixel across the edge takes
colour from the current pixel's side; below: the current pixel takes from across). The integrals of
the piecewise-linear line are evaluated exactly (`ortho_area`); areaTex stores this same function
at distances (i^2, j^2) and bilinearly interpolates in sqrt(distance), so for distances that are
not perfect squares the reference's value is an interpolation of what is computed exactly here.

Diagonal (our own construction from the same principle, see `diag_area`): a 45-degree staircase of
n = dl + dr + 1 step pixels is revectorised through the midpoints of its unit steps (the line
v = u + 1/2 in a frame where the current step pixel is the unit square [0,1]^2 and the steps are
the squares [k,k+1]^2); if the run ends in a horizontal or vertical continuation the true edge is
flatter or steeper there, which in the sheared frame (u, v - u) is exactly an orthogonal crossing
edge, so the end of the line is moved by +-1/2 (vertically) and joined to the run's middle, as in
the orthogonal case. The reference's diagonal texture instead averages several line placements
(its "null" and L patterns are filtered); we do not reproduce that.
"""
from __future__ import annotations

import itertools

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

# Weights, in 1/32, of the four texels of one pseudo-gather fetch (see the module docstring):
# (near, this row), (far, this row), (near, row beyond), (far, row beyond).
GATHER_WEIGHTS_32 = (21, 7, 3, 1)
SEARCH_TABLE_SIZE = 33    # round(32 * value) is 0..32


def search_delta(side: int, along: tuple[int, int, int, int], cross: tuple[int, int, int, int]) -> int:
    """Pixels of the last fetch that still belong to the line (0, 1, 2).

    side 0: search towards -along (left / up), 1: towards +along (right / down).
    along / cross: the four bits (near, far, near beyond, far beyond) of the edge channel followed by
    the search and of the crossing channel. Only the line's own row of `along` matters; crossing
    edges on either row count (they cross the line)."""
    near, far = along[0], along[1]
    # A crossing edge stored at texel p lies on p's -along side (edges texture: left / top edges),
    # on either row (it crosses the line).
    cross_near = cross[0] or cross[2]
    cross_far = cross[1] or cross[3]
    if side == 0:
        # near = p, far = p - 1: cross_near separates near and far, cross_far is beyond far.
        d = 1 if near else 0
        if d == 1 and far and not cross_near:
            d = 2
    else:
        # near = p, far = p + 1: cross_near separates the previous pixel and near,
        # cross_far near and far.
        d = 1 if (near and not cross_near) else 0
        if d == 1 and far and not cross_far:
            d = 2
    return d


def search_delta_table() -> np.ndarray:
    """(2, 33, 33) float32: [side, round(32 * crossing value), round(32 * along value)] -> delta.
    Combinations no fetch can produce stay 0."""
    t = np.zeros((2, SEARCH_TABLE_SIZE, SEARCH_TABLE_SIZE), np.float32)
    seen = np.zeros_like(t, dtype=bool)
    for bits in itertools.product((0, 1), repeat=8):
        along, cross = bits[:4], bits[4:]
        va = sum(w * b for w, b in zip(GATHER_WEIGHTS_32, along))
        vc = sum(w * b for w, b in zip(GATHER_WEIGHTS_32, cross))
        for side in (0, 1):
            d = search_delta(side, along, cross)
            assert not seen[side, vc, va] or t[side, vc, va] == d  # sums are unique: no clash
            t[side, vc, va], seen[side, vc, va] = d, True
    return t


SEARCH_TABLE = search_delta_table()


# ----------------------------------------------------------------------------- areas (Dr.Jit)
def _pos_neg(f0, f1, length):
    """(integral of max(f, 0), integral of max(-f, 0)) over a piece of `length` on which f runs
    linearly from f0 to f1."""
    same_pos = (f0 >= 0.0) & (f1 >= 0.0)
    same_neg = (f0 <= 0.0) & (f1 <= 0.0)
    denom = dr.maximum(dr.abs(f0) + dr.abs(f1), 1e-30)
    tri_pos = dr.square(dr.maximum(f0, f1)) / (2.0 * denom)   # signs differ: one triangle each
    tri_neg = dr.square(dr.minimum(f0, f1)) / (2.0 * denom)
    pos = dr.select(same_pos, (f0 + f1) * 0.5, dr.select(same_neg, 0.0, tri_pos))
    neg = dr.select(same_neg, -(f0 + f1) * 0.5, dr.select(same_pos, 0.0, tri_neg))
    return pos * length, neg * length


def end_height(code, before: float = 0.5):
    """Height of the revectorised line at a segment end from its crossing-edge code
    round(4 * e) (e = 0.25 * before-side edge + 0.75 * after-side edge): 1 -> +before
    (crossing edge on the before side: above / left), 3 -> -before, 0 or 4 -> 0."""
    return dr.select(code == 1.0, before, dr.select(code == 3.0, -before, 0.0))


def ortho_area(dl, dright, h_start, h_end):
    """Orthogonal area function: segment of d = dl + dright + 1 pixels, line through (0, h_start),
    (d/2, 0), (d, h_end) (h > 0 towards the before side: above / left). Returns, for the pixel
    [dl, dl + 1]: (area where the line is on the after side -- the current pixel takes that much
    from the before-side neighbour, SMAA's r / b --, area where it is on the before side -- the
    before-side neighbour takes that much from the current pixel, SMAA's g / a)."""
    d = dl + dright + 1.0
    m = d * 0.5
    t0, t1 = dl, dl + 1.0
    s = dr.clip(m, t0, t1)

    def h(t):
        return dr.select(t <= m, h_start * (m - t) / m, h_end * (t - m) / m)

    h0, hs, h1 = h(t0), h(s), h(t1)
    p1, n1 = _pos_neg(h0, hs, s - t0)
    p2, n2 = _pos_neg(hs, h1, t1 - s)
    return n1 + n2, p1 + p2


def diag_offsets(cc_bottom, cc_top, shift: float = 0.5):
    """End offsets of the diagonal line (in v, the vertical of the '/' frame) from the crossing
    codes cc = 2 * (horizontal continuation) + (vertical continuation) of the run's bottom and top
    ends (0 where the end was not found). A flatter edge (horizontal continuation) raises the
    bottom end and lowers the top end by `shift`; a steeper one (vertical) the opposite; 0 / 3
    (none / both) leave the end on the 45-degree midline."""
    o_bottom = dr.select(cc_bottom == 2.0, shift, dr.select(cc_bottom == 1.0, -shift, 0.0))
    o_top = dr.select(cc_top == 2.0, -shift, dr.select(cc_top == 1.0, shift, 0.0))
    return o_bottom, o_top


def diag_area(dl, dright, o_bottom, o_top):
    """Diagonal area function in the '/' frame: step pixels [k, k+1]^2 for k = -dl .. dright, the
    current one [0, 1]^2, v upwards; the staircase runs along the left and top sides of each step
    pixel. Revectorised line: v = u + 1/2 + delta(u), delta linear from o_bottom at u = -dl to 0 at
    the run's middle u_m = (dright + 1 - dl) / 2 and from there to o_top at u = dright + 1.
    Returns (r, g): r = area of the current pixel above the line (it takes that much from the pixel
    above it), g = area of the pixel above (the square [0,1] x [1,2]) below the line (it takes that
    much from the current pixel). With no offsets r = g = 1/8."""
    n = dl + dright + 1.0
    half = n * 0.5
    um = (dright + 1.0 - dl) * 0.5

    def f(u):  # 1 - (line height), the signed vertical gap of the line below the pixel's top
        delta = dr.select(u <= um, o_bottom * (um - u) / half, o_top * (u - um) / half)
        return 0.5 - u - delta

    zero, one = dr.zeros(mi.Float, dr.width(n)), dr.full(mi.Float, 1.0, dr.width(n))
    s = dr.clip(um, 0.0, 1.0)
    f0, fs, f1 = f(zero), f(s), f(one)
    p1, n1 = _pos_neg(f0, fs, s)
    p2, n2 = _pos_neg(fs, f1, 1.0 - s)
    return p1 + p2, n1 + n2
