"""Rays through pixels, from the reference's own sensor and shading (or Mitsuba's path integrator):
stratified sets of samples per pixel for the adaptive reference, and one ray per pixel centre for
the agreement check."""
from __future__ import annotations

import numpy as np

from backend import dr, mi
from scenes import ResolvedScene
from shading import frame_geometry, shade, trace_visible

from .mitsuba_scene import sensor

_CHUNK_RAYS = 1 << 22    # rays per Dr.Jit launch


_NET_BITS = 16           # a set holds at most 2^16 samples (render_reference's cap per replicate)


def _owen(x, seed):
    """Nested uniform (Owen) scramble of the 32-bit fractions x, one permutation tree per seed:
    Laine and Karras's hash on the bit-reversed value, whose low bits are the fraction's leading
    digits, so each digit is permuted as a function of the digits above it (Burley 2020)."""
    x = dr.brev(x)
    x ^= x * 0x3D20ADEA
    x += seed
    x *= (seed >> 16) | 1
    x ^= x * 0x05526C56
    x ^= x * 0x53A22864
    return dr.brev(x)


def net_points(j, seed0, seed1):
    """Point j (UInt32, < 2^16) of the Owen-scrambled Sobol' (0,2)-sequence whose two dimensions
    are scrambled by seed0 and seed1: the first 2^m points of one scramble are a (0,m,2)-net,
    one point in each of the 2^m cells of every shape 2^-k x 2^-(m-k), each uniform over [0,1)^2."""
    x0 = dr.brev(j)                                   # van der Corput
    # Mitsuba's unscrambled Sobol' dimension 2: below 2^16 points it has 16 significant bits,
    # exact in float32, so its 32-bit fraction is recovered exactly
    x1 = mi.UInt32(mi.sobol_2(j, 0) * mi.Float(2.0 ** 32))
    scale = mi.Float(2.0 ** -24)                      # the leading 24 bits: float32 in [0, 1)
    return mi.Float(_owen(x0, seed0) >> 8) * scale, mi.Float(_owen(x1, seed1) >> 8) * scale


class _PixelTracer:
    """Sums of sets of rays through given pixels, from the reference's own sensor and shading
    (direct transports) or Mitsuba's path integrator (transport 'path'). A set of a samples
    (a power of two) is an Owen-scrambled Sobol' net over the pixel with a scramble of its own:
    every sample is uniform over the pixel's area, the sets are independent of one another, and
    each set is stratified in every cell shape of its size at once. A jittered sx x sy grid is
    one of those shapes; the others (2^m x 1 ... 1 x 2^m) are what many thin texel edges and
    lines at one orientation need, as on a minified texture at a grazing angle."""

    def __init__(self, scene: ResolvedScene, cam, path: bool, mscene, integ, geo):
        self.w, self.h = cam.width, cam.height
        self.sens = sensor(cam, 1)
        self.eye = cam.position
        self.path, self.mscene, self.integ, self.geo = path, mscene, integ, geo
        self.background = mi.Color3f(*scene.desc.background)
        self.sampler = mi.load_dict({"type": "independent"}) if path else None

    def sets(self, pix: np.ndarray, r: int, a: int, seed: int, groups: int | None = None):
        """For each pixel, r independent sets of a samples: their sums (len(pix), r, 3), and each
        set's smallest and largest sample, per channel (len(pix), r, 3) each; with `groups` (a
        divisor of r), the smallest and largest of each of that many runs of consecutive sets
        instead (len(pix), groups, 3): reduced here, not on the host (on a GPU the host's min/max
        over a (n, 32, 3) array was a fifth of a reference's time)."""
        n = len(pix) * r * a
        if a & (a - 1) or a > 1 << _NET_BITS:
            raise ValueError(f"a set holds a power of two samples up to 2^{_NET_BITS}, got {a}")
        # opaque: literal sizes and seeds would be compiled into the kernel, one kernel per call
        a_, ra = dr.opaque(mi.UInt32, a), dr.opaque(mi.UInt32, r * a)
        idx = dr.arange(mi.UInt32, n)
        p = dr.gather(mi.UInt32, mi.UInt32(pix.astype(np.uint32)), idx // ra)
        # one scramble per set, hashed from (seed, set) with TEA as Mitsuba's independent sampler
        # seeds its streams (nearby seeds of a plain hash would give correlated scrambles)
        s0, s1 = mi.sample_tea_32(dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF), idx // a_, 8)
        u, v = net_points(idx % a_, s0, s1)
        pos = mi.Point2f((mi.Float(p % self.w) + u) / self.w, (mi.Float(p // self.w) + v) / self.h)
        if not self.path:
            ray, _ = self.sens.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
            surf, _ = trace_visible(self.geo, mi.Ray3f(ray))
            col = shade(self.geo, surf, self.eye)
        else:
            self.sampler.seed(int(seed) & 0xFFFFFFFF, n)
            ray, _ = self.sens.sample_ray_differential(0.0, self.sampler.next_1d(), pos, mi.Point2f(0.5, 0.5))
            col, valid, _ = self.integ.sample(self.mscene, self.sampler, ray, None, True)
            # as the pilot's alpha film composite: misses (alpha 0) show the background
            col = col + dr.select(valid, 0.0, 1.0) * self.background
        zero = dr.zeros(mi.Float, n)      # broadcast constant channels before summing blocks
        chans = [col[k] + zero for k in range(3)]
        dr.eval(chans)                    # one tracing kernel for the three channels, not one each
        sums = [dr.block_sum(mi.Float64(c), a) for c in chans]   # float64: sets of up to 2^16
        lo = [dr.block_reduce(dr.ReduceOp.Min, c, a) for c in chans]
        hi = [dr.block_reduce(dr.ReduceOp.Max, c, a) for c in chans]
        g = r if groups is None else groups
        if r % g:
            raise ValueError(f"groups must divide the {r} sets, got {groups}")
        if g < r:
            lo = [dr.block_reduce(dr.ReduceOp.Min, c, r // g) for c in lo]
            hi = [dr.block_reduce(dr.ReduceOp.Max, c, r // g) for c in hi]
        dr.eval(sums, lo, hi)
        return tuple(np.stack([np.asarray(c, np.float64) for c in x], -1).reshape(len(pix), n_, 3)
                     for x, n_ in ((sums, r), (lo, g), (hi, g)))

    def chunked(self, pix: np.ndarray, r: int, a: int, rng: np.random.Generator, groups: int | None = None):
        """sets() over pixels pix in launches of at most _CHUNK_RAYS rays."""
        per_chunk = max(1, _CHUNK_RAYS // int(a * r))
        for k in range(0, len(pix), per_chunk):
            g = pix[k:k + per_chunk]
            yield g, *self.sets(g, r, a, seed=rng.integers(1 << 32), groups=groups)


def trace_pixel_centres(scene: ResolvedScene, t: int, width: int, height: int):
    """One Mitsuba ray through each pixel centre: (colour (H,W,3), object id (H,W), triangle (H,W)).

    Used by the agreement check: the same point the raster samples with zero jitter."""
    cam = scene.camera(t, width, height)
    geo = frame_geometry(scene, t)
    sens = sensor(cam, 1)
    idx = dr.arange(mi.UInt32, width * height)
    pos = mi.Point2f((mi.Float(idx % width) + 0.5) / width, (mi.Float(idx // width) + 0.5) / height)
    ray, _ = sens.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    surf, _ = trace_visible(geo, mi.Ray3f(ray))
    col = shade(geo, surf, cam.position)
    rgb = np.stack([np.asarray(col[k]) for k in range(3)], -1).reshape(height, width, 3)
    ids = np.asarray(surf.obj).reshape(height, width).astype(np.int32)
    prim = np.where(ids > 0, np.asarray(surf.prim).reshape(height, width).astype(np.int64), -1)
    return rgb.astype(np.float32), ids, prim.astype(np.int32)
