"""Dr.Jit image helpers on flat, row-major pixel arrays (pixel (x, y) at index y*W + x).

Images are mi.Float (one channel) or mi.Color3f (RGB) of W*H entries. Every neighbourhood read is a
dr.gather with clamped coordinates (clamp-to-edge), the usual texture-sampler behaviour of the
shaders the thesis built on. Everything here is traced lazily and fused by Dr.Jit into few kernels.
"""
from __future__ import annotations

from dataclasses import dataclass

import backend  # noqa: F401
from backend import dr, mi

# Row-major 3x3 offsets (dx, dy); this order is also the tie-break of the closest-depth search
# (the first strictly-closest tap wins, as in INSIDE's find_closest_fragment_3x3).
OFFSETS_3X3 = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
OFFSETS_CROSS = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)]  # the "+" pattern, centre included
REC709 = (0.2126, 0.7152, 0.0722)


class Grid:
    """Pixel coordinates and clamped neighbour indices for one resolution."""

    def __init__(self, width: int, height: int):
        self.w, self.h, self.n = int(width), int(height), int(width) * int(height)
        i = dr.arange(mi.Int32, self.n)
        self.x = i % self.w
        self.y = i // self.w
        self._index: dict[tuple[int, int], object] = {}

    def index(self, dx: int, dy: int):
        """Flat index of pixel (x+dx, y+dy), clamped to the image (clamp-to-edge)."""
        key = (dx, dy)
        if key not in self._index:
            xx = dr.clip(self.x + dx, 0, self.w - 1)
            yy = dr.clip(self.y + dy, 0, self.h - 1)
            self._index[key] = yy * self.w + xx
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
        """INSIDE's box: the mean of the 3x3 and cross values (spec §5 step 3)."""
        return ((self.min3 + self.minx) * 0.5, (self.max3 + self.maxx) * 0.5,
                (self.avg3 + self.avgx) * 0.5)

    def mixed(self, t):
        """Thesis eq. 4.11: mix(cross value, 3x3 value, t)."""
        return (lerp(self.minx, self.min3, t), lerp(self.maxx, self.max3, t),
                lerp(self.avgx, self.avg3, t))


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


def closest_velocity(grid: Grid, depth, motion):
    """Motion vector of the 3x3 pixel with the smallest depth (spec §5 step 1)."""
    o0 = OFFSETS_3X3[0]
    best_d, best_i = grid.tap(depth, *o0), grid.index(*o0)
    for o in OFFSETS_3X3[1:]:
        d = grid.tap(depth, *o)
        closer = d < best_d
        best_d = dr.select(closer, d, best_d)
        best_i = dr.select(closer, grid.index(*o), best_i)
    return dr.gather(mi.Vector2f, motion, best_i)


def reproject(grid: Grid, hist, velocity):
    """Bilinear history fetch at (x + 0.5 - vx, y + 0.5 - vy); `valid` is False off-screen.

    Off-screen means the previous position lies outside [0, W] x [0, H]; inside, the border half
    pixel reads clamp-to-edge like a texture sampler.
    """
    w, h = grid.w, grid.h
    px = mi.Float(grid.x) + 0.5 - velocity.x
    py = mi.Float(grid.y) + 0.5 - velocity.y
    valid = (px >= 0) & (px <= w) & (py >= 0) & (py <= h)
    # Clamp before floor/int conversion: huge velocities must not overflow Int32 (they are invalid
    # anyway, and the clamp does not move any valid position).
    u = dr.clip(px - 0.5, -1.0, float(w))
    v = dr.clip(py - 0.5, -1.0, float(h))
    fu, fv = dr.floor(u), dr.floor(v)
    tx, ty = u - fu, v - fv
    x0, y0 = mi.Int32(fu), mi.Int32(fv)
    x0c, x1c = dr.clip(x0, 0, w - 1), dr.clip(x0 + 1, 0, w - 1)
    y0c, y1c = dr.clip(y0, 0, h - 1), dr.clip(y0 + 1, 0, h - 1)
    T = type(hist)
    h00 = dr.gather(T, hist, y0c * w + x0c)
    h10 = dr.gather(T, hist, y0c * w + x1c)
    h01 = dr.gather(T, hist, y1c * w + x0c)
    h11 = dr.gather(T, hist, y1c * w + x1c)
    return lerp(lerp(h00, h10, tx), lerp(h01, h11, tx), ty), valid


def clip_toward_centre(hist, bmin, bmax, eps: float):
    """INSIDE's clip_aabb (spec §5 step 4): pull `hist` toward the box centre onto the box.

    e >= eps > 0, so a zero-size box gives a finite v/e; m == 0 (hist at the centre) leaves it."""
    p = (bmax + bmin) * 0.5
    e = (bmax - bmin) * 0.5 + eps
    v = hist - p
    a = dr.abs(v / e)
    m = dr.maximum(dr.maximum(a.x, a.y), a.z) if isinstance(a, mi.Color3f) else a
    return dr.select(m > 1.0, p + v / m, hist)


def feedback_weight(lum_c, lum_h, k_min: float, k_max: float, floor: float):
    """INSIDE's luminance feedback (spec §5 step 5): k = mix(k_min, k_max, (1 - d)^2).

    d is saturated to [0, 1]: a no-op for non-negative colours (where d <= 1 already), it keeps k
    inside [k_min, k_max] should a negative colour ever arrive."""
    d = dr.abs(lum_c - lum_h) / dr.maximum(dr.maximum(lum_c, lum_h), floor)
    wgt = dr.square(1.0 - clamp01(d))
    return k_min + (k_max - k_min) * wgt


def sharpen(grid: Grid, img, w: float):
    """Cross kernel [[0,-w,0],[-w,1+4w,-w],[0,-w,0]] as img + w * sum(img - n), clamped to >= 0."""
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
