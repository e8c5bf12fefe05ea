"""Dr.Jit image helpers on flat, row-major pixel arrays (pixel (x, y) at index y*W + x).

Images are mi.Float (one channel) or mi.Color3f (RGB) of W*H entries. Every neighbourhood read is a
dr.gather with clamped coordinates (clamp-to-edge), the usual texture-sampler behaviour of the
shaders the thesis built on. Everything here is traced lazily and fused by Dr.Jit into few kernels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

# Row-major 3x3 offsets (dx, dy); this order is also the tie-break of the closest-depth search
# (the first strictly-closest tap wins, as in INSIDE's find_closest_fragment_3x3).
OFFSETS_3X3 = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
OFFSETS_CROSS = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)]  # the "+" pattern, centre included
REC709 = (0.2126, 0.7152, 0.0722)


class Grid:
    """Pixel coordinates and clamped neighbour indices for one resolution.

    `w`, `h`, `n` are Python ints (shapes, comparisons); kernels use the opaque copies `W`, `H`
    (Int32) and `Wf`, `Hf` (Float), so the size is a kernel parameter, not a literal baked into
    the code, and a second resolution reuses the compiled kernels. `x`, `y` are evaluated once per
    resolution: an integer division by an opaque width would be a scalar loop in every kernel."""

    def __init__(self, width: int, height: int):
        self.w, self.h, self.n = int(width), int(height), int(width) * int(height)
        self.W, self.H = opaque_int(self.w), opaque_int(self.h)
        self.Wf, self.Hf = opaque_float(self.w), opaque_float(self.h)
        i = dr.arange(mi.Int32, self.n)
        self.x = i % self.W
        self.y = i // self.W
        dr.eval(self.x, self.y)
        self._index: dict[tuple[int, int], object] = {}

    def index(self, dx: int, dy: int):
        """Flat index of pixel (x+dx, y+dy), clamped to the image (clamp-to-edge)."""
        key = (dx, dy)
        if key not in self._index:
            xx = dr.clip(self.x + dx, 0, self.W - 1)
            yy = dr.clip(self.y + dy, 0, self.H - 1)
            self._index[key] = yy * self.W + xx
        return self._index[key]

    def tap(self, img, dx: int, dy: int):
        """img at (x+dx, y+dy) for every pixel."""
        if (dx, dy) == (0, 0):
            return img
        return dr.gather(type(img), img, self.index(dx, dy))


@dataclass
class Neighbourhood:
    min3: object
    max3: object
    avg3: object
    minx: object  # cross (+) pattern, 5 taps
    maxx: object
    avgx: object

    def averaged(self):
        """INSIDE's box: the mean of the 3x3 and cross values (Pedersen 2016; Oliveros 2018, §3.6.4)."""
        return ((self.min3 + self.minx) * 0.5, (self.max3 + self.maxx) * 0.5,
                (self.avg3 + self.avgx) * 0.5)

    def mixed(self, t):
        """Thesis eq. 4.11: mix(cross value, 3x3 value, t)."""
        return (lerp(self.minx, self.min3, t), lerp(self.maxx, self.max3, t),
                lerp(self.avgx, self.avg3, t))


def opaque_float(v):
    """`v` as an opaque mi.Float: a per-call constant (a size, a jitter, a camera term) passed to
    the kernel as a parameter, so a new value reuses the compiled kernel (a literal would not)."""
    return dr.opaque(mi.Float, float(v))


def opaque_rcp(v):
    """1 / `v` as an opaque mi.Float: Dr.Jit computes `x / literal` as x times the literal's
    reciprocal, so `x * opaque_rcp(c)` is bit for bit what `x / c` gave with c a literal."""
    return dr.opaque(mi.Float, float(np.float32(1.0) / np.float32(v)))   # in float32, as Dr.Jit


def opaque_int(v):
    """`v` as an opaque mi.Int32 (see opaque_float)."""
    return dr.opaque(mi.Int32, int(v))


def lerp(a, b, t):
    """mix(a, b, t) = a + (b - a) t: exact when a == b, so constant images stay constant."""
    return a + (b - a) * t


def clamp01(x):
    return dr.clip(x, 0.0, 1.0)


def neighbourhood(grid: Grid, img) -> Neighbourhood:
    """min, max and mean over the 3x3 and the cross neighbourhoods."""
    taps = {o: grid.tap(img, *o) for o in OFFSETS_3X3}
    mn, mx, s = taps[OFFSETS_3X3[0]], taps[OFFSETS_3X3[0]], taps[OFFSETS_3X3[0]]
    for o in OFFSETS_3X3[1:]:
        mn, mx, s = dr.minimum(mn, taps[o]), dr.maximum(mx, taps[o]), s + taps[o]
    cmn, cmx, cs = taps[OFFSETS_CROSS[0]], taps[OFFSETS_CROSS[0]], taps[OFFSETS_CROSS[0]]
    for o in OFFSETS_CROSS[1:]:
        cmn, cmx, cs = dr.minimum(cmn, taps[o]), dr.maximum(cmx, taps[o]), cs + taps[o]
    return Neighbourhood(mn, mx, s / 9.0, cmn, cmx, cs / 5.0)


def mean3x3(grid: Grid, img):
    s = grid.tap(img, *OFFSETS_3X3[0])
    for o in OFFSETS_3X3[1:]:
        s = s + grid.tap(img, *o)
    return s / 9.0


def mean_cross(grid: Grid, img):
    s = grid.tap(img, *OFFSETS_CROSS[0])
    for o in OFFSETS_CROSS[1:]:
        s = s + grid.tap(img, *o)
    return s / 5.0


def luminance(c, weights):
    return c.x * weights[0] + c.y * weights[1] + c.z * weights[2]


def closest_index(grid: Grid, depth):
    """Flat index of the 3x3 pixel with the smallest depth (first strictly-closest tap wins)."""
    o0 = OFFSETS_3X3[0]
    best_d, best_i = grid.tap(depth, *o0), grid.index(*o0)
    for o in OFFSETS_3X3[1:]:
        d = grid.tap(depth, *o)
        closer = d < best_d
        best_d = dr.select(closer, d, best_d)
        best_i = dr.select(closer, grid.index(*o), best_i)
    return best_i


def closest_velocity(grid: Grid, depth, motion):
    """Motion vector of the 3x3 pixel with the smallest depth (Karis 2014; Oliveros 2018, §3.6.2)."""
    return dr.gather(mi.Vector2f, motion, closest_index(grid, depth))


def reproject(grid: Grid, hist, velocity):
    """Bilinear history fetch at (x + 0.5 - vx, y + 0.5 - vy); `valid` is False off-screen.

    Off-screen means the previous position lies outside [0, W] x [0, H]; inside, the border half
    pixel reads clamp-to-edge like a texture sampler.
    """
    px, py, valid = previous_position(grid, velocity)
    return bilinear(grid, hist, px, py), valid


def previous_position(grid: Grid, velocity):
    """(px, py, valid): where each pixel's centre was in the previous frame, in pixel units, and
    whether that lies inside [0, W] x [0, H]."""
    px = mi.Float(grid.x) + 0.5 - velocity.x
    py = mi.Float(grid.y) + 0.5 - velocity.y
    valid = (px >= 0) & (px <= grid.Wf) & (py >= 0) & (py <= grid.Hf)
    return px, py, valid


def _texel_coords(grid: Grid, px, py):
    """Integer texel (x0, y0) below-left of (px, py) and the fractions, texel centres at +0.5.

    Clamped before the int conversion: huge positions must not overflow Int32 (clamp-to-edge reads
    the same texels for any position beyond one texel outside the image)."""
    u = dr.clip(px - 0.5, -1.0, grid.Wf)
    v = dr.clip(py - 0.5, -1.0, grid.Hf)
    fu, fv = dr.floor(u), dr.floor(v)
    return mi.Int32(fu), mi.Int32(fv), u - fu, v - fv


def texel(grid: Grid, img, xi, yi):
    """img at integer texel (xi, yi), clamp-to-edge."""
    xc, yc = dr.clip(xi, 0, grid.W - 1), dr.clip(yi, 0, grid.H - 1)
    return dr.gather(type(img), img, yc * grid.W + xc)


def bilinear(grid: Grid, img, px, py):
    """Bilinear sample of `img` at continuous position (px, py) in pixel units (texel centres at
    +0.5), clamp-to-edge addressing, like a GPU linear sampler (but with exact float weights)."""
    x0, y0, tx, ty = _texel_coords(grid, px, py)
    return _bilinear_at(grid, img, x0, tx, y0, ty)


def _bilinear_at(grid: Grid, img, x0, tx, y0, ty):
    w, h = grid.W, grid.H
    x0c, x1c = dr.clip(x0, 0, w - 1), dr.clip(x0 + 1, 0, w - 1)
    y0c, y1c = dr.clip(y0, 0, h - 1), dr.clip(y0 + 1, 0, h - 1)
    T = type(img)
    h00 = dr.gather(T, img, y0c * w + x0c)
    h10 = dr.gather(T, img, y0c * w + x1c)
    h01 = dr.gather(T, img, y1c * w + x0c)
    h11 = dr.gather(T, img, y1c * w + x1c)
    return lerp(lerp(h00, h10, tx), lerp(h01, h11, tx), ty)


def nearest_index(grid: Grid, px, py):
    """Flat index of the texel containing (px, py), clamped to the image."""
    xi = mi.Int32(dr.floor(dr.clip(px, 0.0, grid.Wf)))
    yi = mi.Int32(dr.floor(dr.clip(py, 0.0, grid.Hf)))
    return dr.clip(yi, 0, grid.H - 1) * grid.W + dr.clip(xi, 0, grid.W - 1)


def catmull_rom_weights(t):
    """Catmull-Rom weights of the taps at -1, 0, +1, +2 for a fraction t in [0, 1)."""
    t2 = t * t
    t3 = t2 * t
    return (0.5 * (2.0 * t2 - t - t3),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (4.0 * t2 + t - 3.0 * t3),
            0.5 * (t3 - t2))


def catmull_rom(grid: Grid, img, px, py, five_tap: bool = False):
    """Bicubic Catmull-Rom sample of `img` at (px, py) (pixel units, clamp-to-edge).

    five_tap=False: the exact separable 4x4 filter. It is what the usual "9-tap" shader form
    computes (the two middle taps of each axis merged into one bilinear fetch, exact because
    w1 + w2 > 0); with gathers we take the 16 texels directly.
    five_tap=True: the 5-tap approximation (Jimenez 2016): the 4 corner taps of the 9-tap form are
    dropped and the remaining weights renormalised.
    The result can overshoot (negative lobes); the caller clips it by the neighbourhood box.
    The taps are summed as deviations from texel (x0, y0) (the weights sum to 1, so this is the same
    filter): a constant image is then reproduced exactly, and an integer position gives the texel.
    """
    x0, y0, tx, ty = _texel_coords(grid, px, py)
    wx, wy = catmull_rom_weights(tx), catmull_rom_weights(ty)
    ref = texel(grid, img, x0, y0)
    if not five_tap:
        out = None
        for j in range(4):
            row = None
            for i in range(4):
                v = (texel(grid, img, x0 + (i - 1), y0 + (j - 1)) - ref) * wx[i]
                row = v if row is None else row + v
            out = row * wy[j] if out is None else out + row * wy[j]
        return ref + out
    w12x, w12y = wx[1] + wx[2], wy[1] + wy[2]
    fx, fy = wx[2] / w12x, wy[2] / w12y          # offset of the merged middle tap from x0 / y0
    zero = dr.zeros(mi.Float, grid.n)
    taps = ((_bilinear_at(grid, img, x0 - 1, zero, y0, fy), wx[0] * w12y),
            (_bilinear_at(grid, img, x0, fx, y0 - 1, zero), w12x * wy[0]),
            (_bilinear_at(grid, img, x0, fx, y0, fy), w12x * w12y),
            (_bilinear_at(grid, img, x0 + 2, zero, y0, fy), wx[3] * w12y),
            (_bilinear_at(grid, img, x0, fx, y0 + 2, zero), w12x * wy[3]))
    total, wsum = (taps[0][0] - ref) * taps[0][1], taps[0][1]
    for v, wgt in taps[1:]:
        total, wsum = total + (v - ref) * wgt, wsum + wgt
    return ref + total / wsum


def rgb_to_ycocg(c):
    """RGB -> YCoCg (Y = R/4 + G/2 + B/4, Co = R/2 - B/2, Cg = -R/4 + G/2 - B/4)."""
    return mi.Color3f(0.25 * c.x + 0.5 * c.y + 0.25 * c.z,
                      0.5 * c.x - 0.5 * c.z,
                      0.5 * c.y - 0.25 * c.x - 0.25 * c.z)


def ycocg_to_rgb(c):
    """YCoCg -> RGB (R = Y + Co - Cg, G = Y + Cg, B = Y - Co - Cg), the exact inverse."""
    return mi.Color3f(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z)


def variance_box(grid: Grid, img, gamma: float):
    """Salvi's variance box over the 3x3: (mu - gamma sigma, mu + gamma sigma, mu), per channel.

    The moments are taken of the deviations from the centre pixel (a shift that makes a constant
    neighbourhood give sigma = 0 and mu = the constant exactly, and avoids the cancellation of
    E[x^2] - E[x]^2 on large values); the variance is clamped at 0 before the square root."""
    s1 = s2 = None
    for o in OFFSETS_3X3:
        d = grid.tap(img, *o) - img
        s1 = d if s1 is None else s1 + d
        s2 = d * d if s2 is None else s2 + d * d
    m1 = s1 / 9.0
    sigma = dr.sqrt(dr.maximum(s2 / 9.0 - m1 * m1, 0.0))
    mu = img + m1
    return mu - sigma * gamma, mu + sigma * gamma, mu


def karis_blend_weight(c, h, k, weights):
    """The history weight k' such that lerp(c, h, k') equals blending in the invertible tone-mapped
    space T(x) = x / (1 + luma(x)) with weight k and mapping back with T^-1(y) = y / (1 - luma(y)):
    k' = k w_h / ((1 - k) w_c + k w_h), w = 1 / (1 + luma). (Karis 2014.) Negative lumas count as 0.
    Written as a weight so a pixel whose history equals its colour stays exactly that colour."""
    wc = 1.0 / (1.0 + dr.maximum(luminance(c, weights), 0.0))
    wh = 1.0 / (1.0 + dr.maximum(luminance(h, weights), 0.0))
    kh = k * wh
    return kh / ((1.0 - k) * wc + kh)


def _max3(a):
    return dr.maximum(dr.maximum(a.x, a.y), a.z) if isinstance(a, mi.Color3f) else a


def clip_toward_centre(hist, bmin, bmax, eps: float, tol: float = 0.0):
    """INSIDE's clip_aabb (Pedersen 2016; Oliveros 2018, §3.6.4), made well conditioned in float32: pull `hist` toward
    the box centre p onto the box widened by a tolerance tau, then clamp it into the box itself.

        p = (bmax + bmin)/2,  half = (bmax - bmin)/2,  v = hist - p,
        tau = eps + tol * (max_c |p_c| + max_c half_c),  e = half + tau,  m = max_c |v_c| / e_c,
        h = p + v/m if m > 1 else hist;   result = clamp(h, bmin, bmax).

    Why: INSIDE's eps (1e-8) is far below float32's resolution for colours of 0.1-1 (ulp 6e-8 at
    1), so rounding decided its clip: a history on a box face rounded to m slightly above 1, and in
    a zero-width channel (e = eps) 5e-8 of rounding gave m ~ 5 and dragged every channel five-fold
    toward p. With tau relative to the box's magnitude (max-norm of centre plus half-size: the size
    of the numbers whose rounding it must absorb; one scale for all channels since YCoCg channels
    mix RGB), a history inside the box within tau is not clipped, and a channel narrower than tau
    drives m only when the history is off it by more than tau, i.e. by a real colour difference,
    which then clips as INSIDE's does. The clip's amplification of a change in v, |v|/e, is at
    most ~1/tol. The clamp (1-Lipschitz) takes back the <= tau by which the widened box exceeds
    the real one, so the history stays inside the neighbourhood's range as with INSIDE (no
    negative colours from the tolerance); the result differs from INSIDE's clip by at most tau
    per channel wherever INSIDE's is not itself decided by rounding. tol = 0: INSIDE's clip, then
    the clamp (<= eps apart). eps > 0 keeps v/e finite for a zero-size box; m == 0 leaves hist."""
    p = (bmax + bmin) * 0.5
    half = (bmax - bmin) * 0.5
    tau = eps
    if tol != 0.0:
        tau = eps + tol * (_max3(dr.abs(p)) + _max3(half))
    v = hist - p
    m = _max3(dr.abs(v / (half + tau)))
    return dr.clip(dr.select(m > 1.0, p + v / m, hist), bmin, bmax)


def feedback_weight(lum_c, lum_h, k_min: float, k_max: float, floor: float):
    """INSIDE's luminance feedback (Pedersen 2016; Oliveros 2018, §3.6.3): k = mix(k_min, k_max, (1 - d)^2).

    d is saturated to [0, 1]: a no-op for non-negative colours (where d <= 1 already), it keeps k
    inside [k_min, k_max] should a negative colour ever arrive."""
    d = dr.abs(lum_c - lum_h) / dr.maximum(dr.maximum(lum_c, lum_h), floor)
    wgt = dr.square(1.0 - clamp01(d))
    return k_min + (k_max - k_min) * wgt


def sharpen(grid: Grid, img, w: float):
    """Cross kernel [[0,-w,0],[-w,1+4w,-w],[0,-w,0]] as img + w * sum(img - n), clamped to >= 0
    (the displayed output: a negative radiance cannot be shown; see taa_impl.baseline)."""
    if w == 0.0:
        return dr.maximum(img, 0.0)
    s = img - grid.tap(img, 0, -1)
    s += img - grid.tap(img, -1, 0)
    s += img - grid.tap(img, 1, 0)
    s += img - grid.tap(img, 0, 1)
    return dr.maximum(img + s * w, 0.0)


def sobel(grid: Grid, f):
    """Sobel gradient magnitude, Gx = [[-1,0,1],[-2,0,2],[-1,0,1]], Gy = [[1,2,1],[0,0,0],[-1,-2,-1]]
    (row 0 is the row above, y - 1)."""
    t = {o: grid.tap(f, *o) for o in OFFSETS_3X3 if o != (0, 0)}
    gx = (t[(1, -1)] + 2.0 * t[(1, 0)] + t[(1, 1)]) - (t[(-1, -1)] + 2.0 * t[(-1, 0)] + t[(-1, 1)])
    gy = (t[(-1, -1)] + 2.0 * t[(0, -1)] + t[(1, -1)]) - (t[(-1, 1)] + 2.0 * t[(0, 1)] + t[(1, 1)])
    return dr.sqrt(gx * gx + gy * gy)
