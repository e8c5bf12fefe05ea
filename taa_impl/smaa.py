"""SMAA 1x (Jimenez, Echevarria, Sousa, Gutierrez 2012, "SMAA: Enhanced Subpixel Morphological
Antialiasing"), in Dr.Jit, following the three passes of the reference shader (SMAA.hlsl 2.8):

 1. Luma edge detection on the display image. luma = dot(encoded RGB, weights), 'rec709'
    (0.2126, 0.7152, 0.0722: the weights SMAALumaEdgeDetectionPS uses, on gamma-encoded colour) or
    'rec601' (0.299, 0.587, 0.114). A pixel gets a left / top edge when |L - L_left| / |L - L_top|
    >= threshold and that delta is at least 1 / local_contrast_adaptation of the largest delta among
    left, top, right, bottom, left-left and top-top (the reference's local contrast adaptation,
    factor 2).
 2. Blending weights, per pixel with an edge, four values: (r, g) for its top edge -- r: how much the
    pixel takes from the pixel above, g: how much the pixel above takes from it -- and (b, a) for its
    left edge (b: the pixel from its left neighbour, a: the left neighbour from it).
    - Diagonals first (for pixels with a top edge; max_search_steps_diag > 0): searches along both
      diagonals, one pixel per step, while the step pixels carry both of their edges (the '\'
      search reads a pixel's top and right edges); runs of >= 4 pixels get the diagonal area
      (`smaa_area.diag_area_lookup`) from their two distances and the crossing codes at the run's
      ends (cleared where the end was not found within the search range); the '\' run is looked up
      in the '/' frame flipped vertically (distances up-left, down-right; r and g swapped), as the
      reference does. A pixel with a diagonal skips steps below, its left edge included, as in the
      reference.
    - Orthogonal: searches left / right (top edge) or up / down (left edge) with one bilinear
      fetch per two pixels (the "pseudo gather4": offsets -0.25 / -0.125 px), while both fetched
      pixels carry the edge and no crossing edge is seen, at most max_search_steps fetches a side;
      the last fetch is decoded through the search function (`smaa_area.SEARCH_TABLE`) to the
      exact end pixel. The crossing edges at both ends are read with one bilinear fetch each
      (0.25 * before side + 0.75 * after side) and the area function
      (`smaa_area.ortho_area_lookup`: L, Z and U shapes, a '+' end facing a bend as a Z, short U
      shapes smoothed) gives the two weights.
    - Corner rounding: if the crossing edge at the nearer end continues for a second pixel (a real
      corner, not a one-pixel stair step), the weight on that side is scaled by
      corner_rounding / 100 (both ends at the same distance: half each); 100 = off.
 3. Neighbourhood blending: each pixel reads its own r and b and its right neighbour's a and its
    bottom neighbour's g; if their sum is below min_blend_weight it is left as is; otherwise the
    larger of max(horizontal) and max(vertical) picks the direction (ties: vertical) and the pixel
    is the weight-normalised sum of two bilinear fetches moved by those weights towards the two
    neighbours.

Presets: defaults are SMAA_PRESET_ULTRA (threshold 0.05, 32 search steps, 16 diagonal steps, corner
rounding 25); `SMAA_PRESETS` holds the others (low, medium, high) as parameter overrides.

Area functions (`area`, see smaa_area's docstring): 'reference' (the default, and what the study's
SMAA column uses) evaluates them as the reference's area texture holds them -- orthogonal areas at
squared distances interpolated in sqrt(distance), diagonal areas by 30 x 30 point sampling, both
as 8-bit bytes (computed here; they equal the reference's AreaTex.h byte for byte) -- so the
weights are the reference shader's. 'exact' integrates the same revectorised lines exactly at the
actual distances (closer to the paper's definition). The two differ by up to 0.079 in an
orthogonal weight (at non-square distances; < 1/255 at squares) and 0.018 in a diagonal one; on
the quick static test the column moves by at most 0.7 dB (pipe: 38.55 reference, 39.23 exact).

Choices and deviations (see also smaa_area's docstring):
- Input: the display image, `display.encode(colour)` (tone map + sRGB, floats in [0, 1]); the output
  is display-encoded (output_space 'display'), clamped to [0, 1].
- blend_space 'linear' (default): the reference asks for sRGB reads and writes in the blending pass
  only, so the bilinear mixes happen in linear light: we sRGB-decode the display image for the
  fetches and re-encode the mix. 'display' blends the encoded values directly (what happens when
  sRGB reads are not available). Pixels that are not blended are returned bit-exactly.
- Area and search tables are computed here from their definitions, not copied (smaa_area).
- Texture reads use clamp-to-edge, like the reference's samplers, with exact float bilinear weights
  (GPUs quantise them to ~8 bits; the pseudo-gather values are exact multiples of 1/32 either way,
  and the area texture is read at exact float sqrt distances). The blending pass reads the weights
  clamp-to-edge too, as the reference does: a pixel in the last column takes its own a as its
  right neighbour's, one in the bottom row its own g as its bottom neighbour's.
- Edge search, area and blending are symmetric under transposing the image, except that (as in the
  reference) diagonals are only searched from top edges and their weights always blend vertically,
  and the blending pass sends ties max(horizontal) == max(vertical) to vertical.

What it does to a long straight edge: no crossing edge within reach of the searches (or none at
all), so both ends have height 0 and the area is 0: the pixels are left exactly as they are.
Blending happens only within max_search_steps * 2 pixels of a stair step or of the edge's end.
"""
from __future__ import annotations

from dataclasses import dataclass


import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from . import smaa_area as A
from .base import DisplayImageTechnique

LUMAS = {"rec709": (0.2126, 0.7152, 0.0722), "rec601": (0.299, 0.587, 0.114)}
BLEND_SPACES = ("linear", "display")

# Parameter overrides of the reference's presets (SMAA.hlsl); the defaults are ULTRA.
SMAA_PRESETS: dict[str, dict] = {
    "low": dict(threshold=0.15, max_search_steps=4, max_search_steps_diag=0, corner_rounding=100.0),
    "medium": dict(threshold=0.1, max_search_steps=8, max_search_steps_diag=0, corner_rounding=100.0),
    "high": dict(threshold=0.1, max_search_steps=16, max_search_steps_diag=8, corner_rounding=25.0),
    "ultra": dict(threshold=0.05, max_search_steps=32, max_search_steps_diag=16, corner_rounding=25.0),
}

# Fixed geometry of the reference's texture reads (not tuning knobs), in pixels.
SEARCH_START_NEG = 0.25     # first left/up fetch: 0.25 px before the pixel's centre (-0.25 px)
SEARCH_START_POS = 1.75     # first right/down fetch: +1.25 px from the centre
SEARCH_ACROSS = 0.375       # search fetches sit -0.125 px across the line from the centre
SEARCH_CONTINUE = 0.8281    # fetched edge value above which both fetched pixels carry the edge
SEARCH_BIAS = 3.25          # undoes the -0.25 offset, the search's bias of 1 and the last step
CROSSING_ACROSS = 0.25      # crossing-edge fetch: -0.25 px across (0.25 before + 0.75 after side)
DIAG_CONTINUE = 0.9         # mean of the two edges of a diagonal step pixel: both on
DIAG_MIN_SUM = 2.0          # a diagonal needs d1 + d2 > 2, i.e. a run of at least 4 pixels
MAX_SEARCH_STEPS_REFERENCE = 112       # SMAA_MAX_SEARCH_STEPS range [0, 112]
MAX_SEARCH_STEPS_DIAG_REFERENCE = 20   # SMAA_MAX_SEARCH_STEPS_DIAG range [0, 20]


@dataclass(frozen=True)
class SMAAParams:
    threshold: float = 0.05                 # SMAA_THRESHOLD (luma delta)
    max_search_steps: int = 32              # SMAA_MAX_SEARCH_STEPS (fetches of 2 px per side)
    max_search_steps_diag: int = 16         # SMAA_MAX_SEARCH_STEPS_DIAG (0: no diagonals)
    corner_rounding: float = 25.0           # SMAA_CORNER_ROUNDING, percent (100: no corner detection)
    local_contrast_adaptation: float = 2.0  # SMAA_LOCAL_CONTRAST_ADAPTATION_FACTOR
    luma: str = "rec709"                    # luma weights on the encoded values: 'rec709' | 'rec601'
    blend_space: str = "linear"             # 'linear' (sRGB-decoded fetches) | 'display'
    min_blend_weight: float = 1e-5          # pixels whose four weights sum below this are kept
    area: str = "reference"                 # 'reference': areaTex as the reference tabulates it
    #                                         (the study's column) | 'exact' (see smaa_area)

    def __post_init__(self):
        if not 0.0 < self.threshold <= 1.0:
            raise ValueError("threshold must be in (0, 1]")
        for f, lo in (("max_search_steps", 1), ("max_search_steps_diag", 0)):
            v = getattr(self, f)
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"{f} must be an integer >= {lo}")
            object.__setattr__(self, f, int(v))
        if not 0.0 <= self.corner_rounding <= 100.0:
            raise ValueError("corner_rounding must be in [0, 100]")
        object.__setattr__(self, "corner_rounding", float(self.corner_rounding))
        if not self.local_contrast_adaptation > 0.0:
            raise ValueError("local_contrast_adaptation must be > 0")
        if self.luma not in LUMAS:
            raise ValueError(f"luma must be one of {sorted(LUMAS)}")
        if self.blend_space not in BLEND_SPACES:
            raise ValueError(f"blend_space must be one of {BLEND_SPACES}")
        if not self.min_blend_weight >= 0.0:
            raise ValueError("min_blend_weight must be >= 0")
        if self.area not in A.AREA_MODES:
            raise ValueError(f"area must be one of {A.AREA_MODES}, got {self.area!r}")
        # The reference's ranges; its area texture covers exactly these search lengths.
        if self.area == "reference" and self.max_search_steps > MAX_SEARCH_STEPS_REFERENCE:
            raise ValueError(f"max_search_steps must be <= {MAX_SEARCH_STEPS_REFERENCE} with "
                             "area='reference' (the area texture's range); use area='exact'")
        if self.area == "reference" and self.max_search_steps_diag > MAX_SEARCH_STEPS_DIAG_REFERENCE:
            raise ValueError(f"max_search_steps_diag must be <= {MAX_SEARCH_STEPS_DIAG_REFERENCE} "
                             "with area='reference' (the area texture's range); use area='exact'")


class SMAA(DisplayImageTechnique):
    """debug_terms(): luma, edge_left, edge_top (0/1), weight_r/g/b/a (the blending weights) and
    diagonal (1 where the top-edge weights came from the diagonal pass)."""
    name = "smaa"
    Params = SMAAParams

    @staticmethod
    def kernel(grid, rgb, params):
        return smaa(grid, rgb, params)


# ------------------------------------------------------------------------------ pass 1
def luma_edges(grid: K.Grid, rgb, p: SMAAParams):
    """SMAALumaEdgeDetectionPS: (edges as mi.Vector2f (left, top) of 0/1, luma)."""
    L = K.luminance(rgb, LUMAS[p.luma])
    dr.eval(L)
    tap = grid.tap
    Ll, Lt = tap(L, -1, 0), tap(L, 0, -1)
    d_left, d_top = dr.abs(L - Ll), dr.abs(L - Lt)
    d_right, d_bottom = dr.abs(L - tap(L, 1, 0)), dr.abs(L - tap(L, 0, 1))
    d_ll, d_tt = dr.abs(Ll - tap(L, -2, 0)), dr.abs(Lt - tap(L, 0, -2))
    final = dr.maximum(dr.maximum(dr.maximum(d_left, d_right), dr.maximum(d_ll, d_top)),
                       dr.maximum(d_bottom, d_tt))
    f = p.local_contrast_adaptation
    left = (d_left >= p.threshold) & (final <= f * d_left)
    top = (d_top >= p.threshold) & (final <= f * d_top)
    E = mi.Vector2f(dr.select(left, 1.0, 0.0), dr.select(top, 1.0, 0.0))
    dr.eval(E)
    return E, L


# ------------------------------------------------------------------------------ pass 2
class _Axis:
    """A line direction: 'h' follows top edges along x (crossing edges: left edges), 'v' follows
    left edges along y (crossing edges: top edges). Every orthogonal step is written once in
    (along, across) coordinates, so the two directions are exact transposes of each other."""

    def __init__(self, kind: str):
        self.kind = kind
        self.cross = 0 if kind == "h" else 1   # component of E (x: left, y: top)
        self.cont = 1 if kind == "h" else 0

    def xy(self, along, across):
        return (along, across) if self.kind == "h" else (across, along)

    @staticmethod
    def comp(v, c):
        return v.x if c == 0 else v.y


def _search(grid, E, along_i, across, axis: _Axis, direction: int, steps: int):
    """SMAASearchXLeft/XRight/YUp/YDown: the centre coordinate (along) of the end pixel."""
    n = dr.width(along_i)
    a = mi.Float(along_i) + (SEARCH_START_NEG if direction < 0 else SEARCH_START_POS)
    end = a + 2.0 * steps * direction
    e_cross, e_cont = dr.zeros(mi.Float, n), dr.full(mi.Float, 1.0, n)
    for _ in range(steps):
        go = ((a > end) if direction < 0 else (a < end)) & (e_cont > SEARCH_CONTINUE) & (e_cross == 0.0)
        v = K.bilinear(grid, E, *axis.xy(a, across))
        e_cross = dr.select(go, axis.comp(v, axis.cross), e_cross)
        e_cont = dr.select(go, axis.comp(v, axis.cont), e_cont)
        a = dr.select(go, a + 2.0 * direction, a)
        dr.eval(a, e_cross, e_cont)
    size = A.SEARCH_TABLE_SIZE
    side = 0 if direction < 0 else 1
    ti = (side * size * size + mi.UInt32(dr.round(32.0 * e_cross)) * size
          + mi.UInt32(dr.round(32.0 * e_cont)))
    delta = dr.gather(mi.Float, _search_table(), ti)
    return a + SEARCH_BIAS - delta if direction < 0 else a - SEARCH_BIAS + delta


_SEARCH_TABLE_DR = None


def _search_table():
    global _SEARCH_TABLE_DR
    if _SEARCH_TABLE_DR is None:
        _SEARCH_TABLE_DR = mi.Float(A.SEARCH_TABLE.reshape(-1))
    return _SEARCH_TABLE_DR


def ortho_weights(grid, E, xi, yi, axis: _Axis, p: SMAAParams):
    """Weights (after-side pixel takes from before side, before side takes from after side) of the
    top edge ('h': SMAA's r, g) or left edge ('v': b, a) of the pixels (xi, yi); also the distances."""
    along_i, across_i = (xi, yi) if axis.kind == "h" else (yi, xi)
    centre = mi.Float(along_i) + 0.5
    across = mi.Float(across_i) + SEARCH_ACROSS
    c_neg = _search(grid, E, along_i, across, axis, -1, p.max_search_steps)
    c_pos = _search(grid, E, along_i, across, axis, +1, p.max_search_steps)
    d_neg, d_pos = dr.abs(c_neg - centre), dr.abs(c_pos - centre)
    cross_at = mi.Float(across_i) + CROSSING_ACROSS
    e1 = axis.comp(K.bilinear(grid, E, *axis.xy(c_neg, cross_at)), axis.cross)
    e2 = axis.comp(K.bilinear(grid, E, *axis.xy(c_pos + 1.0, cross_at)), axis.cross)
    code1, code2 = dr.round(4.0 * e1), dr.round(4.0 * e2)
    w_after, w_before = A.ortho_area_lookup(d_neg, d_pos, code1, code2, p.area)
    if p.corner_rounding < 100.0:
        near_neg = mi.Float(d_neg <= d_pos)
        near_pos = mi.Float(d_pos <= d_neg)
        k = (1.0 - p.corner_rounding / 100.0) / (near_neg + near_pos)
        r_neg, r_pos = near_neg * k, near_pos * k
        end_neg = along_i - mi.Int32(d_neg)          # end pixel towards -along
        beyond_pos = along_i + mi.Int32(d_pos) + 1   # the pixel after the +along end pixel

        def crossing(al, ac):
            return axis.comp(K.texel(grid, E, *axis.xy(al, ac)), axis.cross)

        f_after = (1.0 - r_neg * crossing(end_neg, across_i + 1)
                   - r_pos * crossing(beyond_pos, across_i + 1))
        f_before = (1.0 - r_neg * crossing(end_neg, across_i - 2)
                    - r_pos * crossing(beyond_pos, across_i - 2))
        w_after = w_after * dr.clip(f_after, 0.0, 1.0)
        w_before = w_before * dr.clip(f_before, 0.0, 1.0)
    return w_after, w_before, d_neg, d_pos


def _diag_search(grid, E, xi, yi, dx: int, dy: int, steps: int, second: bool):
    """SMAASearchDiag1 (second=False: the pixel's (left, top) edges) / SMAASearchDiag2 (second=True:
    its (right, top) edges). Returns (distance z, w = mean of the last fetch's two edges (> 0.9: the
    end was not found), top edge of the last fetched pixel)."""
    n = dr.width(xi)
    z, w = dr.full(mi.Float, -1.0, n), dr.full(mi.Float, 1.0, n)
    last_top = dr.zeros(mi.Float, n)
    px, py = mi.Int32(xi), mi.Int32(yi)
    for _ in range(steps):
        go = (z < float(steps - 1)) & (w > DIAG_CONTINUE)
        px = dr.select(go, px + dx, px)
        py = dr.select(go, py + dy, py)
        z = dr.select(go, z + 1.0, z)
        here = K.texel(grid, E, px, py)
        side = K.texel(grid, E, px + 1, py).x if second else here.x
        last_top = dr.select(go, here.y, last_top)
        w = dr.select(go, (side + here.y) * 0.5, w)
        dr.eval(px, py, z, w, last_top)
    return z, w, last_top


def diag_weights(grid, E, xi, yi, e, p: SMAAParams):
    """SMAACalculateDiagWeights: (r, g) of the top edge from the two diagonal directions."""
    steps = p.max_search_steps_diag
    n = dr.width(xi)
    zero = dr.zeros(mi.Float, n)

    def tex(x, y):
        return K.texel(grid, E, x, y)

    # '/' : step pixels (x + k, y - k) with left and top edges; the bottom end may be one pixel
    # with a top edge only.
    has_left = e.x > 0.0
    z1, w1, top1 = _diag_search(grid, E, xi, yi, -1, +1, steps, False)
    d_bot = dr.select(has_left, z1 + dr.select(top1 > DIAG_CONTINUE, 1.0, 0.0), zero)
    w_bot = dr.select(has_left, w1, zero)
    d_top, w_top, _ = _diag_search(grid, E, xi, yi, +1, -1, steps, False)
    ib, it = mi.Int32(d_bot), mi.Int32(d_top)
    cc_bot = 2.0 * tex(xi - ib - 1, yi + ib).y + tex(xi - ib, yi + ib).x
    cc_top = 2.0 * tex(xi + it + 1, yi - it).y + tex(xi + it + 1, yi - it - 1).x
    cc_bot = dr.select(w_bot >= DIAG_CONTINUE, 0.0, cc_bot)   # end not found: no crossing edge
    cc_top = dr.select(w_top >= DIAG_CONTINUE, 0.0, cc_top)
    r1, g1 = A.diag_area_lookup(d_bot, d_top, cc_bot, cc_top, p.area, steps)
    ok1 = d_bot + d_top > DIAG_MIN_SUM

    # '\' : step pixels (x + k, y + k) with top and right edges; mirrored, the same construction.
    d_top2, w_top2, _ = _diag_search(grid, E, xi, yi, -1, -1, steps, True)
    has_right = tex(xi + 1, yi).x > 0.0
    z2, w2, top2 = _diag_search(grid, E, xi, yi, +1, +1, steps, True)
    d_bot2 = dr.select(has_right, z2 + dr.select(top2 > DIAG_CONTINUE, 1.0, 0.0), zero)
    w_bot2 = dr.select(has_right, w2, zero)
    it2, ib2 = mi.Int32(d_top2), mi.Int32(d_bot2)
    cc_top2 = 2.0 * tex(xi - it2 - 1, yi - it2).y + tex(xi - it2, yi - it2 - 1).x
    cc_bot2 = 2.0 * tex(xi + ib2 + 1, yi + ib2).y + tex(xi + ib2 + 1, yi + ib2).x
    cc_top2 = dr.select(w_top2 >= DIAG_CONTINUE, 0.0, cc_top2)
    cc_bot2 = dr.select(w_bot2 >= DIAG_CONTINUE, 0.0, cc_bot2)
    # The '\' run is the '/' frame flipped vertically (the pixel above and the current one
    # trade places): its up-left end is the frame's bottom end, and r and g swap.
    g2, r2 = A.diag_area_lookup(d_top2, d_bot2, cc_top2, cc_bot2, p.area, steps)
    ok2 = d_bot2 + d_top2 > DIAG_MIN_SUM

    r = dr.select(ok1, r1, 0.0) + dr.select(ok2, r2, 0.0)
    g = dr.select(ok1, g1, 0.0) + dr.select(ok2, g2, 0.0)
    return r, g


def blending_weights(grid: K.Grid, E, p: SMAAParams):
    """SMAABlendingWeightCalculationPS for every pixel: ((r, g, b, a) full-size mi.Float arrays,
    diagonal flag as mi.Float). Computed only on the pixels with an edge."""
    n = grid.n
    out = [dr.zeros(mi.Float, n) for _ in range(5)]
    idx = dr.compress((E.x > 0.0) | (E.y > 0.0))
    if dr.width(idx) == 0:
        return tuple(out[:4]), out[4]
    xi, yi = dr.gather(mi.Int32, grid.x, idx), dr.gather(mi.Int32, grid.y, idx)   # = ii % w, ii // w
    e = dr.gather(mi.Vector2f, E, idx)
    has_left, has_top = e.x > 0.0, e.y > 0.0
    if p.max_search_steps_diag > 0:
        rd, gd = diag_weights(grid, E, xi, yi, e, p)
        diag = has_top & ((rd + gd) != 0.0)     # the reference's weights.r == -weights.g test
    else:
        rd = gd = dr.zeros(mi.Float, dr.width(idx))
        diag = dr.zeros(mi.Bool, dr.width(idx))
    hr, hg, _, _ = ortho_weights(grid, E, xi, yi, _Axis("h"), p)
    vb, va, _, _ = ortho_weights(grid, E, xi, yi, _Axis("v"), p)
    r = dr.select(has_top, dr.select(diag, rd, hr), 0.0)
    g = dr.select(has_top, dr.select(diag, gd, hg), 0.0)
    vert = has_left & ~diag
    b = dr.select(vert, vb, 0.0)
    a = dr.select(vert, va, 0.0)
    for arr, val in zip(out, (r, g, b, a, dr.select(diag, 1.0, 0.0))):
        dr.scatter(arr, val, idx)
    dr.eval(*out)
    return tuple(out[:4]), out[4]


# ------------------------------------------------------------------------------ pass 3
def srgb_decode(c):
    c = dr.clip(c, 0.0, 1.0)
    return dr.select(c <= 0.04045, c / 12.92, dr.power((c + 0.055) / 1.055, 2.4))


def srgb_encode(lin):
    lin = dr.clip(lin, 0.0, 1.0)
    return dr.select(lin <= 0.0031308, lin * 12.92, 1.055 * dr.power(lin, 1.0 / 2.4) - 0.055)


def neighbourhood_blend(grid: K.Grid, rgb, weights, p: SMAAParams):
    """SMAANeighborhoodBlendingPS on the display-encoded image `rgb` with weights (r, g, b, a)."""
    R, G, B, Aw = weights
    # Clamp-to-edge reads, as the reference's sampler: the last column reads its own a as its
    # right neighbour's, the bottom row its own g.
    a_x = grid.tap(Aw, 1, 0)    # right neighbour's a
    a_y = grid.tap(G, 0, 1)     # bottom neighbour's g
    a_z, a_w = B, R                                                  # own b (left), r (top)
    blend = (a_x + a_y + a_z + a_w) >= p.min_blend_weight
    horiz = dr.maximum(a_x, a_z) > dr.maximum(a_y, a_w)
    w1 = dr.select(horiz, a_x, a_y)
    w2 = dr.select(horiz, a_z, a_w)
    s = w1 + w2
    s = dr.select(s > 0.0, s, 1.0)
    w1, w2 = w1 / s, w2 / s
    cx, cy = mi.Float(grid.x) + 0.5, mi.Float(grid.y) + 0.5
    p1x, p1y = cx + dr.select(horiz, a_x, 0.0), cy + dr.select(horiz, 0.0, a_y)
    p2x, p2y = cx - dr.select(horiz, a_z, 0.0), cy - dr.select(horiz, 0.0, a_w)
    src = srgb_decode(rgb) if p.blend_space == "linear" else rgb
    dr.eval(src)
    mixed = K.bilinear(grid, src, p1x, p1y) * w1 + K.bilinear(grid, src, p2x, p2y) * w2
    if p.blend_space == "linear":
        mixed = srgb_encode(mixed)
    out = dr.select(blend, dr.clip(mixed, 0.0, 1.0), rgb)
    dr.eval(out)
    return out


def smaa(grid: K.Grid, rgb, p: SMAAParams):
    """SMAA 1x on the display-encoded image `rgb` (mi.Color3f); returns (image, terms)."""
    E, luma = luma_edges(grid, rgb, p)
    weights, diag = blending_weights(grid, E, p)
    out = neighbourhood_blend(grid, rgb, weights, p)
    terms = {"luma": luma, "edge_left": E.x, "edge_top": E.y, "weight_r": weights[0],
             "weight_g": weights[1], "weight_b": weights[2], "weight_a": weights[3],
             "diagonal": diag}
    return out, terms
