"""SMAA's lookup functions, computed here from their definitions (nothing is copied from the
reference's precomputed areaTex / searchTex or from the script that builds them).

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

Orthogonal area function (what areaTex holds for straight edges)
-----------------------------------------------------------------
MLAA revectorisation (Jimenez et al. 2011/2012): an edge segment of d = dl + dr + 1 pixels, the
current pixel covering [dl, dl + 1] along it. The crossing edges at each end are read as
code = round(4 e), e = 0.25 * (edge on the before side: above / left) + 0.75 * (after side), and
say how the true edge bends there:
  1 -> towards the before side: the line starts at height +1/2 (the middle of the crossing edge);
  3 -> towards the after side: -1/2;   0 -> no bend: 0;
  4 -> crossing edges on both sides (a '+' end): the opposite of the other end's bend, so such an
       end facing a single bend makes a full Z (the ends of 1-pixel lines and hair strands); facing
       no bend or another '+' it stays 0 (no stair step to revectorise).
The line runs from the first end's height to 0 at the segment's middle d/2 and on to the second
end's height: L (one end bent), Z (opposite bends: one straight line), U (the same bend at both
ends). The weights are the areas between that line and the edge inside the pixel: where the line
is below the edge (after side) the pixel takes that much from the pixel before it (SMAA's r / b);
where it is above, the pixel before takes that much from this one (g / a).
Short U shapes are smoothed: each half's area A becomes lerp(sqrt(2 A) / 2, A, min(d / 32, 1)),
so a short bump blends more than its revectorised triangles, converging to them at d = 32 (the
reference's smoothing of U patterns; sqrt(2 A) / 2 >= A for A <= 1/2).

Diagonal area function (what areaTex holds for 45-degree runs)
---------------------------------------------------------------
In the frame of a '/' run (y up): its n = dl + dr + 1 step pixels are the unit squares
[1 + k, 2 + k] x [k, 1 + k], k = 0 .. n - 1, each with an edge on its left and its top side; the
current pixel is k = dl and the pixel above it, across its top edge, is [1 + dl, 2 + dl]^2. The
staircase's outer corners (1 + k, 1 + k) lie on y = x, its inner corners (1 + k, k) on y = x - 1.
The revectorised line is the (infinite) line through one point at each end of the run:
  bottom end: 'in' (1, 0), 'out' (1, 1), or 'out_before' (0, 0) (the outer corner one step before);
  top end:    'in' (n + 1, n), 'out' (n + 1, n + 1), or 'out_last' (n, n) (the last step's corner).
The crossing code of each end, cc = 2 * (edge continues horizontally) + (continues vertically), read
by the shader's fetches and 0 where the end was not found within the search, picks the point: a
vertical continuation makes the edge steeper (bottom 'in', top 'out'), a horizontal one flatter
(bottom 'out', top 'in'). Ends that do not tell (0: nothing, 3: both) average two lines (DIAG_LINES):
the lines to 'in' and 'out' (code 3) or to 'in' and the outer corner inside / before the run
(code 0) when the other end is known, and the two 45-degree lines through the outer and through
the inner corners when neither end is known (a long straight diagonal: r = g = 1/4, where the line
through the steps' midpoints would give 1/8). The weights are r = area of the current pixel above
the line (it takes that much from the pixel above) and g = area of the pixel above below the line.

Tabulation: area='reference' (the default) and area='exact'
-----------------------------------------------------------
'reference' evaluates the two functions as the reference's area texture holds them, which is what
the SMAA every reader knows computes: orthogonal areas at squared distances (i^2, j^2),
i, j = 0..15, bilinearly interpolated at (sqrt(dl), sqrt(dr)) (the texture's quadratic distance
compression: exact only where both distances are perfect squares); diagonal areas at integer
distances 0..19, by counting the points of a closed 30 x 30 lattice over the pixel that lie
strictly below the line (in float64, in the order the reference evaluates it); both truncated to
8 bits (floor(255 a) / 255), the texture's byte storage. 'exact' integrates the same lines
exactly at the actual distances (float32; the diagonal table is exact at its integer distances).
"""
from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

AREA_MODES = ("reference", "exact")
SMOOTH_MAX_DISTANCE = 32.0   # U shapes shorter than this are smoothed
ORTHO_TEXELS = 16            # reference texture: distances i^2, i = 0..15, per axis and pattern
ORTHO_CODES = 5              # round(4 e) = 0..4 (2 never occurs)
DIAG_TEXELS = 20             # reference texture: diagonal distances 0..19
DIAG_CODES = 4               # cc = 0..3
DIAG_SAMPLES = 30            # reference: a closed 30 x 30 lattice of points per pixel
TEXTURE_LEVELS = 255.0       # 8-bit UNORM storage
MIN_DIAG_PAIR = 3            # dl + dr > 2: shorter runs are not diagonals (their table entries stay 0)

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


# ----------------------------------------------------------------------------- array ops
class _Ops:
    """The few array functions the area code needs, for NumPy (float64 tables) and Dr.Jit
    (float32 per pixel), so one definition serves both."""

    def __init__(self, select, clip, sqrt, maximum, minimum, square, absolute):
        self.select, self.clip, self.sqrt = select, clip, sqrt
        self.maximum, self.minimum, self.square, self.abs = maximum, minimum, square, absolute


NP = _Ops(np.where, np.clip, np.sqrt, np.maximum, np.minimum, np.square, np.abs)
DR = _Ops(dr.select, dr.clip, dr.sqrt, dr.maximum, dr.minimum, dr.square, dr.abs)


def _pos_neg(f0, f1, length, xp):
    """(integral of max(f, 0), integral of max(-f, 0)) over a piece of `length` on which f runs
    linearly from f0 to f1."""
    same_pos = (f0 >= 0.0) & (f1 >= 0.0)
    same_neg = (f0 <= 0.0) & (f1 <= 0.0)
    denom = xp.maximum(xp.abs(f0) + xp.abs(f1), 1e-30)
    tri_pos = xp.square(xp.maximum(f0, f1)) / (2.0 * denom)   # signs differ: one triangle each
    tri_neg = xp.square(xp.minimum(f0, f1)) / (2.0 * denom)
    pos = xp.select(same_pos, (f0 + f1) * 0.5, xp.select(same_neg, 0.0, tri_pos))
    neg = xp.select(same_neg, -(f0 + f1) * 0.5, xp.select(same_pos, 0.0, tri_neg))
    return pos * length, neg * length


# ----------------------------------------------------------------------------- orthogonal
def ortho_heights(code1, code2, xp=DR):
    """Heights (h1, h2) of the revectorised line at the two ends (h > 0 towards the before side)
    from the crossing codes round(4 e), and whether the pattern is a U (same bend at both ends)."""
    def bend(c):
        return xp.select(c == 1.0, 0.5, xp.select(c == 3.0, -0.5, 0.0))

    b1, b2 = bend(code1), bend(code2)
    h1 = xp.select(code1 == 4.0, -b2, b1)    # a '+' end mirrors the other end's bend
    h2 = xp.select(code2 == 4.0, -b1, b2)
    return h1, h2, h1 * h2 > 0.0


def ortho_area(dl, dright, code1, code2, xp=DR):
    """Orthogonal area function at distances (dl, dright) with crossing codes (code1, code2):
    (r, g) = (area of the pixel [dl, dl + 1] where the line is on the after side, where it is on
    the before side), U shapes smoothed."""
    h1, h2, u = ortho_heights(code1, code2, xp)
    d = dl + dright + 1.0
    m = d * 0.5
    t0, t1 = dl, dl + 1.0
    s = xp.clip(m, t0, t1)

    def h(t):
        return xp.select(t <= m, h1 * (m - t) / m, h2 * (t - m) / m)

    h0, hs, he = h(t0), h(s), h(t1)
    p1, n1 = _pos_neg(h0, hs, s - t0, xp)     # the half of the line from the first end
    p2, n2 = _pos_neg(hs, he, t1 - s, xp)     # the half to the second end
    k = xp.clip(d / SMOOTH_MAX_DISTANCE, 0.0, 1.0)

    def smooth(a):
        b = xp.sqrt(2.0 * a) * 0.5
        return xp.select(u, b + (a - b) * k, a)

    return smooth(n1) + smooth(n2), smooth(p1) + smooth(p2)


def _to_bytes(a):
    """The reference texture's storage: int(255 a) (truncation) as UNORM8."""
    return np.floor(TEXTURE_LEVELS * np.asarray(a, np.float64)) / TEXTURE_LEVELS


@lru_cache(maxsize=None)
def ortho_table() -> np.ndarray:
    """(5, 5, 16, 16, 2) float32: [code1, code2, i, j] -> (r, g) at distances (i^2, j^2), as bytes.
    Code 2 never occurs; its slots stay 0."""
    c1, c2, i, j = np.meshgrid(*(np.arange(n, dtype=np.float64) for n in
                                 (ORTHO_CODES, ORTHO_CODES, ORTHO_TEXELS, ORTHO_TEXELS)), indexing="ij")
    r, g = ortho_area(i * i, j * j, c1, c2, NP)
    t = np.stack([_to_bytes(r), _to_bytes(g)], -1)
    t[(c1 == 2) | (c2 == 2)] = 0.0
    return t.astype(np.float32)


_DR_TABLES: dict = {}


def _dr_table(name: str, build):
    if name not in _DR_TABLES:
        t = build()
        _DR_TABLES[name] = (mi.Float(np.ascontiguousarray(t[..., 0]).reshape(-1)),
                            mi.Float(np.ascontiguousarray(t[..., 1]).reshape(-1)), t.shape)
    return _DR_TABLES[name]


def ortho_area_lookup(dl, dright, code1, code2, mode: str):
    """(r, g) per pixel (Dr.Jit): 'exact' evaluates `ortho_area`; 'reference' interpolates the
    byte table bilinearly at (sqrt(dl), sqrt(dr)), as the shader samples its texture."""
    if mode == "exact":
        return ortho_area(dl, dright, code1, code2, DR)
    tr, tg, _ = _dr_table("ortho", ortho_table)
    n = ORTHO_TEXELS
    si, sj = dr.sqrt(dl), dr.sqrt(dright)
    fi, fj = dr.floor(si), dr.floor(sj)
    ti, tj = si - fi, sj - fj
    i0 = dr.minimum(mi.UInt32(fi), n - 1)
    j0 = dr.minimum(mi.UInt32(fj), n - 1)
    i1, j1 = dr.minimum(i0 + 1, n - 1), dr.minimum(j0 + 1, n - 1)
    base = (mi.UInt32(code1) * ORTHO_CODES + mi.UInt32(code2)) * (n * n)
    out = []
    for table in (tr, tg):
        def at(i, j):
            return dr.gather(mi.Float, table, base + i * n + j)
        lo = dr.lerp(at(i0, j0), at(i0, j1), tj)
        hi = dr.lerp(at(i1, j0), at(i1, j1), tj)
        out.append(dr.lerp(lo, hi, ti))
    return out[0], out[1]


# ----------------------------------------------------------------------------- diagonal
# Line placements of the diagonal area function, per (bottom cc, top cc): one or two (bottom
# point, top point) pairs; two are averaged (see the module docstring for the rule).
DIAG_LINES: dict[tuple[int, int], tuple[tuple[str, str], ...]] = {
    (1, 2): (("in", "in"),),                           # steeper below, flatter above
    (2, 2): (("out", "in"),),                          # flats at both ends: flatter line
    (1, 1): (("in", "out"),),                          # verticals at both ends: steeper line
    (2, 1): (("out", "out"),),
    (1, 0): (("in", "out_last"), ("in", "in")),        # top end unknown
    (2, 0): (("out", "out_last"), ("out", "in")),
    (0, 2): (("out_before", "in"), ("in", "in")),      # bottom end unknown
    (0, 1): (("out_before", "out"), ("in", "out")),
    (3, 2): (("out", "in"), ("in", "in")),             # bottom end both ways
    (3, 1): (("out", "out"), ("in", "out")),
    (1, 3): (("in", "out"), ("in", "in")),             # top end both ways
    (2, 3): (("out", "out"), ("out", "in")),
    (0, 0): (("out", "out"), ("in", "in")),            # neither end tells: the two 45-degree lines
    (3, 3): (("out", "out"), ("in", "in")),
    (3, 0): (("out", "out_last"), ("in", "in")),
    (0, 3): (("out_before", "out"), ("in", "in")),
}


def diag_points(name: str, end: str, n):
    """(x, y) of a line point at the 'bottom' or 'top' end of a run of n step pixels."""
    if end == "bottom":
        return {"in": (1.0, 0.0), "out": (1.0, 1.0), "out_before": (0.0, 0.0)}[name]
    return {"in": (1.0 + n, 0.0 + n), "out": (1.0 + n, 1.0 + n), "out_last": (0.0 + n, 0.0 + n)}[name]


def _below_exact(px, py, qx, qy, x0, y0):
    """Exact area of the unit square with lower-left corner (x0, y0) below the line through
    (px, py), (qx, qy) (rising: qx > px, qy > py)."""
    s = (qy - py) / (qx - px)
    a = py + s * (x0 - px) - y0      # the line's height over the square's bottom at its left side

    def F(t):                        # antiderivative of clip(t, 0, 1)
        return np.where(t < 0.0, 0.0, np.where(t > 1.0, t - 0.5, 0.5 * t * t))

    return (F(a + s) - F(a)) / s


_LATTICE = np.arange(DIAG_SAMPLES, dtype=np.float64) / float(DIAG_SAMPLES - 1)


def _below_sampled(px, py, qx, qy, x0, y0):
    """Fraction of the closed lattice (x0 + i / 29, y0 + j / 29) strictly below the line (points
    on it count as above), evaluated as the reference does: the sign of
    (qy - py) (x - xm) + (px - qx) (y - ym) with (xm, ym) the midpoint of the two points."""
    xm, ym = (px + qx) / 2.0, (py + qy) / 2.0
    a, b = qy - py, px - qx
    x = (x0[..., None] + _LATTICE)[..., :, None]
    y = (y0[..., None] + _LATTICE)[..., None, :]
    c = a[..., None, None] * (x - xm[..., None, None]) + b[..., None, None] * (y - ym[..., None, None])
    return np.count_nonzero(c > 0.0, axis=(-2, -1)) / float(DIAG_SAMPLES * DIAG_SAMPLES)


@lru_cache(maxsize=None)
def diag_table(mode: str, size: int = DIAG_TEXELS) -> np.ndarray:
    """(4, 4, size, size, 2) float32: [cc bottom, cc top, dl, dr] -> (r, g) of a '/' run.
    'reference': lattice-sampled and stored as bytes; 'exact': exact areas. Entries with
    dl + dr < 3 (no diagonal) stay 0."""
    below = _below_sampled if mode == "reference" else _below_exact
    dl, dright = np.meshgrid(np.arange(size, dtype=np.float64), np.arange(size, dtype=np.float64),
                             indexing="ij")
    n = dl + dright + 1.0
    used = dl + dright >= MIN_DIAG_PAIR
    t = np.zeros((DIAG_CODES, DIAG_CODES, size, size, 2), np.float64)
    # the current pixel [1 + dl, 2 + dl] x [dl, 1 + dl] and the one above it
    cx, cy, ux, uy = 1.0 + dl[used], 0.0 + dl[used], 1.0 + dl[used], 1.0 + dl[used]
    nu = n[used]
    for (cb, ct), lines in DIAG_LINES.items():
        r = g = None
        for bottom, top in lines:
            (px, py), (qx, qy) = diag_points(bottom, "bottom", nu), diag_points(top, "top", nu)
            px, py = np.broadcast_to(px, nu.shape), np.broadcast_to(py, nu.shape)
            rk, gk = 1.0 - below(px, py, qx, qy, cx, cy), below(px, py, qx, qy, ux, uy)
            if mode == "exact":   # drop float64 noise, so areas that are 0 (or 1) are exactly that
                rk, gk = np.round(rk, 12), np.round(gk, 12)
            r, g = (rk, gk) if r is None else ((r + rk) / 2.0, (g + gk) / 2.0)
        if mode == "reference":
            r, g = _to_bytes(r), _to_bytes(g)
        t[cb, ct][used] = np.stack([r, g], -1)
    return t.astype(np.float32)


def diag_area_lookup(dl, dright, cc1, cc2, mode: str, max_steps: int):
    """(r, g) of a '/' run per pixel (Dr.Jit) from the table of `mode`: distances are integers,
    so the shader's bilinear read lands on texel centres and is a plain lookup. 'exact' tables
    cover every distance the search can return; the reference's texture stops at 19 (a distance
    of 20, possible only with max_search_steps_diag = 20, reads texel 19)."""
    size = DIAG_TEXELS if mode == "reference" else max(DIAG_TEXELS, max_steps + 1)
    tr, tg, _ = _dr_table(f"diag_{mode}_{size}", lambda: diag_table(mode, size))
    i = dr.minimum(mi.UInt32(dl), size - 1)
    j = dr.minimum(mi.UInt32(dright), size - 1)
    idx = ((mi.UInt32(cc1) * DIAG_CODES + mi.UInt32(cc2)) * size + i) * size + j
    return dr.gather(mi.Float, tr, idx), dr.gather(mi.Float, tg, idx)
