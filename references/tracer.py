"""Rays through pixels, from the reference's own sensor and shading (or Mitsuba's path integrator):
stratified sets of samples per pixel for the adaptive reference, and one ray per pixel centre for
the agreement check."""
from __future__ import annotations

import math

import numpy as np

from backend import dr, mi
from scenes import ResolvedScene
from shading import frame_geometry, shade, trace_visible

from .mitsuba_scene import sensor

_CHUNK_RAYS = 1 << 22    # rays per Dr.Jit launch


def _strata(p: int) -> tuple[int, int]:
    sx = max(d for d in range(1, math.isqrt(p) + 1) if p % d == 0)
    return sx, p // sx


class _PixelTracer:
    """Sums of sets of rays through given pixels, from the reference's own sensor and shading
    (direct transports) or Mitsuba's path integrator (transport 'path'). A set of a samples is
    a jittered sx x sy grid over the pixel (one uniform sample per cell), so every sample is
    uniform over the pixel's area and the set is stratified."""

    def __init__(self, scene: ResolvedScene, cam, path: bool, mscene, integ, geo):
        self.w, self.h = cam.width, cam.height
        self.sens = sensor(cam, 1)
        self.eye = cam.position
        self.path, self.mscene, self.integ, self.geo = path, mscene, integ, geo
        self.background = mi.Color3f(*scene.desc.background)
        self.sampler = mi.load_dict({"type": "independent"}) if path else None

    def sets(self, pix: np.ndarray, r: int, a: int, seed: int):
        """For each pixel, r independent sets of a samples: their sums (len(pix), r, 3), and the
        smallest and largest sample of all r a, per channel (len(pix), 3) each."""
        n = len(pix) * r * a
        # opaque: literal sizes and seeds would be compiled into the kernel, one kernel per call
        sx, sy = (dr.opaque(mi.UInt32, x) for x in _strata(a))
        a_, ra = dr.opaque(mi.UInt32, a), dr.opaque(mi.UInt32, r * a)
        idx = dr.arange(mi.UInt32, n)
        j = idx % a_
        p = dr.gather(mi.UInt32, mi.UInt32(pix.astype(np.uint32)), idx // ra)
        # PCG32 streams that differ only in a nearby sequence number are correlated: hash the
        # state from (seed, index) with TEA, as Mitsuba's independent sampler does
        s0, s1 = mi.sample_tea_32(dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF), idx)
        rng = mi.PCG32(size=n, initstate=mi.UInt64(s0) | (mi.UInt64(s1) << 32), initseq=mi.UInt64(idx))
        u = (mi.Float(j % sx) + rng.next_float32()) / mi.Float(sx)
        v = (mi.Float(j // sx) + rng.next_float32()) / mi.Float(sy)
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
        lo = [dr.block_reduce(dr.ReduceOp.Min, c, r * a) for c in chans]
        hi = [dr.block_reduce(dr.ReduceOp.Max, c, r * a) for c in chans]
        dr.eval(sums, lo, hi)
        sums = np.stack([np.asarray(c, np.float64) for c in sums], -1).reshape(len(pix), r, 3)
        return sums, np.stack([np.asarray(c, np.float64) for c in lo], -1), \
            np.stack([np.asarray(c, np.float64) for c in hi], -1)

    def chunked(self, pix: np.ndarray, r: int, a: int, rng: np.random.Generator):
        """sets() over pixels pix in launches of at most _CHUNK_RAYS rays."""
        per_chunk = max(1, _CHUNK_RAYS // int(a * r))
        for k in range(0, len(pix), per_chunk):
            g = pix[k:k + per_chunk]
            yield g, *self.sets(g, r, a, seed=rng.integers(1 << 32))


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
