"""Plain-NumPy reference of the baseline TAA (Xu 2016; Pedersen 2016; Oliveros 2018,
§3.6) and the improved TAA (Oliveros 2018, Improved Sampling for Temporal Anti-Aliasing, §4.3).

Written for clarity, not speed, and independently of taa_impl's Dr.Jit kernels: per-pixel loops
for the velocity search and the bilinear fetch, the sharpen and Sobel kernels applied as the
matrices the thesis prints. The arithmetic runs in the dtype of the inputs (OracleTAA casts the
frame to its `dtype`): float32 agrees with the Dr.Jit version to ~1e-6 frame by frame; float64 is
the well-conditioned reference the float32 kernels are held to over whole sequences
(tests/test_taa_robust.py). Constants are Python floats so they take the arrays' dtype.
It expects finite inputs (the repair of non-finite pixels is tested separately).

The extension switches of TAAParams (taa_impl/baseline.py) are here too, each in its textbook form: YCoCg as a
matrix, the variance as the two-pass population variance, Catmull-Rom as the cubic's matrix form
over explicit texel weights (the 5-tap variant as the 4x4 weights without the corners,
renormalised), Karis's blend literally in c / (1 + luma) space followed by the inverse map, and
rejection by per-pixel lookups in the stored previous buffers.
"""
from __future__ import annotations

import numpy as np

F = np.float32
NINE = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]   # row-major
CROSS = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)]
SHARPEN = {
    "xu": [[0, -1, 0], [-1, 5, -1], [0, -1, 0]],
    "normalised": [[0, -.25, 0], [-.25, 2, -.25], [0, -.25, 0]],
    "none": [[0, 0, 0], [0, 1, 0], [0, 0, 0]],
}
GX = [[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]]
GY = [[1, 2, 1], [0, 0, 0], [-1, -2, -1]]


def tap(img, dx, dy):
    """img[y+dy, x+dx] for every pixel, coordinates clamped to the image."""
    h, w = img.shape[:2]
    ys, xs = np.indices((h, w))
    return img[np.clip(ys + dy, 0, h - 1), np.clip(xs + dx, 0, w - 1)]


def min_max_avg(img, offsets):
    taps = [tap(img, dx, dy) for dx, dy in offsets]
    lo, hi, total = taps[0], taps[0], taps[0]
    for t in taps[1:]:
        lo, hi, total = np.minimum(lo, t), np.maximum(hi, t), total + t
    return lo, hi, total / len(offsets)


def convolve3x3(img, kernel):
    """sum_ij kernel[j][i] * img[y + j - 1, x + i - 1] (kernel row 0 = the row above)."""
    out = np.zeros_like(img)
    for j in range(3):
        for i in range(3):
            if kernel[j][i] != 0:
                out = out + float(kernel[j][i]) * tap(img, i - 1, j - 1)
    return out


def lum(c, weights):
    return c[..., 0] * float(weights[0]) + c[..., 1] * float(weights[1]) + c[..., 2] * float(weights[2])


def closest_velocity(depth, motion, return_index=False):
    """Motion of the 3x3 neighbour with the smallest depth; ties go to the first in NINE order."""
    h, w = depth.shape
    ys, xs = np.indices((h, w))
    best_y, best_x = None, None
    for dx, dy in NINE:
        yy, xx = np.clip(ys + dy, 0, h - 1), np.clip(xs + dx, 0, w - 1)
        if best_y is None:
            best_y, best_x = yy, xx
            continue
        closer = depth[yy, xx] < depth[best_y, best_x]
        best_y, best_x = np.where(closer, yy, best_y), np.where(closer, xx, best_x)
    vel = motion[best_y, best_x]
    where = np.stack([best_y, best_x], -1)
    return (vel, where) if return_index else vel


YCOCG = np.array([[0.25, 0.5, 0.25], [0.5, 0.0, -0.5], [-0.25, 0.5, -0.25]])
YCOCG_INV = np.array([[1.0, 1.0, -1.0], [1.0, 0.0, 1.0], [1.0, -1.0, -1.0]])
CATMULL_ROM = 0.5 * np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]])


def to_ycocg(c):
    return np.einsum("ij,...j->...i", YCOCG, c.astype(np.float64)).astype(c.dtype)


def from_ycocg(c):
    return np.einsum("ij,...j->...i", YCOCG_INV, c.astype(np.float64)).astype(c.dtype)


def variance_box(img, gamma):
    """mu -/+ gamma sigma over the 3x3, population variance."""
    taps = np.stack([tap(img, dx, dy) for dx, dy in NINE]).astype(np.float64)
    mu = taps.mean(axis=0)
    sigma = np.sqrt(((taps - mu) ** 2).mean(axis=0))
    return (mu - gamma * sigma).astype(img.dtype), (mu + gamma * sigma).astype(img.dtype)


def catmull_rom_weights(t):
    """Weights of the taps at -1, 0, 1, 2: [t^3, t^2, t, 1] @ the Catmull-Rom basis matrix."""
    return np.array([t ** 3, t ** 2, t, 1.0]) @ CATMULL_ROM


def catmull_rom_history(hist, vel, five_tap=False):
    """Catmull-Rom at (x + 0.5 - vx, y + 0.5 - vy) from explicit 4x4 texel weights (clamp to edge);
    five_tap drops the 4 corner texels and renormalises. valid as for bilinear_history."""
    h, w = hist.shape[:2]
    out = np.zeros_like(hist)
    valid = np.zeros((h, w), bool)
    D = vel.dtype.type
    for y in range(h):
        for x in range(w):
            px = float(D(x + 0.5) - vel[y, x, 0])
            py = float(D(y + 0.5) - vel[y, x, 1])
            valid[y, x] = 0 <= px <= w and 0 <= py <= h
            if not valid[y, x]:
                continue
            u, v = px - 0.5, py - 0.5
            x0, y0 = int(np.floor(u)), int(np.floor(v))
            wgt = np.outer(catmull_rom_weights(v - y0), catmull_rom_weights(u - x0))  # [j, i]
            if five_tap:
                wgt[0, 0] = wgt[0, 3] = wgt[3, 0] = wgt[3, 3] = 0.0
                wgt /= wgt.sum()
            acc = np.zeros(hist.shape[2:])
            for j in range(4):
                for i in range(4):
                    yy = min(max(y0 + j - 1, 0), h - 1)
                    xx = min(max(x0 + i - 1, 0), w - 1)
                    acc += wgt[j, i] * hist[yy, xx]
            out[y, x] = acc
    return out.astype(hist.dtype), valid


def tonemap_blend(c, h, k, weights):
    """Karis: T(x) = x / (1 + luma), blend there, T^-1(y) = y / (1 - luma(y))."""
    def luma(x):
        return np.maximum(lum(x.astype(np.float64), weights), 0.0)[..., None]
    tc, th = c / (1.0 + luma(c)), h / (1.0 + luma(h))
    t = tc + k * (th - tc)
    return (t / (1.0 - luma(t))).astype(c.dtype)


def rejection(params, frame, where, vel, prev_depth, prev_ids):
    """True where the history is rejected (see taa_impl.baseline.TAATechnique._rejection)."""
    h, w = where.shape[:2]
    out = np.zeros((h, w), bool)
    D = vel.dtype.type
    for y in range(h):
        for x in range(w):
            px = float(D(x + 0.5) - vel[y, x, 0])
            py = float(D(y + 0.5) - vel[y, x, 1])
            xn = min(max(int(np.floor(min(max(px, 0.0), w))), 0), w - 1)
            yn = min(max(int(np.floor(min(max(py, 0.0), h))), 0), h - 1)
            by, bx = where[y, x]
            if params.reject_depth is not None:
                expected = float(frame["prev_depth"][by, bx])
                out[y, x] |= abs(float(prev_depth[yn, xn]) - expected) > params.reject_depth * abs(expected)
            if params.reject_id:
                out[y, x] |= prev_ids[yn, xn] != frame["object_id"][by, bx]
    return out


def bilinear_history(hist, vel):
    """History at (x + 0.5 - vx, y + 0.5 - vy); valid = inside [0, W] x [0, H]."""
    h, w = hist.shape[:2]
    ys, xs = np.indices((h, w))
    D = vel.dtype
    px = (xs + 0.5).astype(D) - vel[..., 0]
    py = (ys + 0.5).astype(D) - vel[..., 1]
    valid = (px >= 0) & (px <= w) & (py >= 0) & (py <= h)
    u, v = np.where(valid, px, 0.5) - 0.5, np.where(valid, py, 0.5) - 0.5
    x0, y0 = np.floor(u).astype(int), np.floor(v).astype(int)
    tx, ty = (u - x0.astype(D))[..., None], (v - y0.astype(D))[..., None]

    def at(xx, yy):
        return hist[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]
    top = at(x0, y0) * (1.0 - tx) + at(x0 + 1, y0) * tx
    bottom = at(x0, y0 + 1) * (1.0 - tx) + at(x0 + 1, y0 + 1) * tx
    out = np.where(valid[..., None], top * (1.0 - ty) + bottom * ty, 0.0).astype(hist.dtype)
    return out, valid


def clip_toward_centre(hist, bmin, bmax, eps, tol=0.0):
    """Toward p onto the box widened by tau = eps + tol * (max|p| + max half-size), then clamped
    into the box (taa_impl.kernels.clip_toward_centre says why)."""
    p = (bmax + bmin) * 0.5
    half = (bmax - bmin) * 0.5
    tau = float(eps) + float(tol) * (np.abs(p).max(axis=-1, keepdims=True)
                                     + half.max(axis=-1, keepdims=True))
    v = hist - p
    m = np.max(np.abs(v / (half + tau)), axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        clipped = p + v / m
    return np.clip(np.where(m > 1, clipped, hist), bmin, bmax)


def feedback(lc, lh, params):
    d = np.abs(lc - lh) / np.maximum(np.maximum(lc, lh), float(params.feedback_floor))
    wgt = (1.0 - np.clip(d, 0, 1)) ** 2
    return float(params.k_min) + (float(params.k_max) - float(params.k_min)) * wgt


def mix(a, b, t):
    return a * (1.0 - t) + b * t


class OracleTAA:
    """improved=False: the baseline (Oliveros 2018, §3.6); improved=True: the thesis's TAA (§4.3). `params` is a taa_impl params dataclass.
    dtype: the arithmetic's precision (the frame is cast to it; the history is kept in it)."""

    def __init__(self, params, improved: bool, dtype=np.float32):
        self.p, self.improved = params, improved
        self.dtype = np.dtype(dtype)
        self.history = None
        self.sobel_history = None
        self.prev_depth = self.prev_ids = None
        self.rejected = None
        self.terms = {}

    def process(self, frame, far, reset=False):
        p = self.p
        D = self.dtype
        c = frame["color"].astype(D)
        if reset or (self.history is not None and self.history.shape != c.shape):
            self.history = self.sobel_history = None
            self.prev_depth = self.prev_ids = None
        vel, where = closest_velocity(frame["depth"].astype(D), frame["motion"].astype(D),
                                      return_index=True)
        ycocg = getattr(p, "box", "minmax") == "ycocg"
        cs = to_ycocg(c) if ycocg else c
        lo3, hi3, avg3 = min_max_avg(cs, NINE)
        lox, hix, avgx = min_max_avg(cs, CROSS)
        if self.improved:
            a = self._aliased_value(frame, D.type(far), vel)[..., None]
            cmin, cmax = mix(lox, lo3, a), mix(hix, hi3, a)
            bmin, bmax = mix(c, cmin, a), mix(c, cmax, a)
        else:
            bmin, bmax = (lo3 + lox) / 2.0, (hi3 + hix) / 2.0
            if p.variance_clip_gamma is not None:
                vmin, vmax = variance_box(cs, p.variance_clip_gamma)
                if p.variance_intersect:
                    bmin, bmax = np.maximum(bmin, vmin), np.minimum(bmax, vmax)
                else:
                    bmin, bmax = vmin, vmax
        self.rejected = None   # mask of rejected pixels, when a rejection test ran
        if self.history is None:
            blend = c
        else:
            if p.history_filter == "bilinear":
                h, valid = bilinear_history(self.history, vel)
            else:
                h, valid = catmull_rom_history(self.history, vel, p.history_filter == "catmull_rom_5")
            if p.reject_depth is not None or p.reject_id:
                rej = rejection(p, frame, where, vel, self.prev_depth, self.prev_ids)
                self.rejected = rej
                valid = valid & ~rej
            tol = getattr(p, "clip_tol", 0.0)
            if ycocg:
                h = from_ycocg(clip_toward_centre(to_ycocg(h), bmin, bmax, p.clip_eps, tol))
            else:
                h = clip_toward_centre(h, bmin, bmax, p.clip_eps, tol)
            k = feedback(lum(c, p.feedback_luma), lum(h, p.feedback_luma), p)[..., None]
            if p.tonemap_blend:
                mixed = tonemap_blend(c, h, k, p.tonemap_luma)
            else:
                mixed = c + k * (h - c)
            blend = np.where(valid[..., None], mixed, c)
        self.prev_depth = frame["depth"].astype(D) if p.reject_depth is not None else None
        self.prev_ids = frame["object_id"].copy() if p.reject_id else None
        self.history = blend.astype(D)
        return np.maximum(convolve3x3(self.history, SHARPEN[p.sharpen]), 0).astype(D)

    def _aliased_value(self, frame, far, vel):
        p, t = self.p, self.terms
        D = self.dtype
        z = frame["depth"].astype(D) / far
        zprev = frame["prev_depth"].astype(D) / far
        # Sobel of albedo luminance, colour luminance and normalised depth.
        mags = []
        for img in (lum(frame["albedo"].astype(D), p.sobel_luma),
                    lum(frame["color"].astype(D), p.sobel_luma), z):
            gx, gy = convolve3x3(img, GX), convolve3x3(img, GY)
            mags.append(np.sqrt(gx * gx + gy * gy))
        u, l, d = mags
        g = np.clip(float(p.sobel_weight_albedo) * u + float(p.sobel_weight_color) * l
                    + float(p.sobel_weight_depth) * d, 0, 1)
        s = np.sqrt(g * g * (3.0 - 2.0 * g))
        t["sobel_raw"] = s
        # Its own TAA: clamp to the averaged 3x3/cross box, one channel, no sharpen.
        if self.sobel_history is not None:
            lo3, hi3, _ = min_max_avg(s, NINE)
            lox, hix, _ = min_max_avg(s, CROSS)
            hs, valid = bilinear_history(self.sobel_history[..., None], vel)
            hs = np.clip(hs[..., 0], (lo3 + lox) / 2.0, (hi3 + hix) / 2.0)
            k = feedback(s, hs, p)
            s = np.where(valid, s + k * (hs - s), s)
        self.sobel_history = s.astype(D)
        t["sobel"] = s
        t["sobelAvgCross"] = min_max_avg(s, CROSS)[2]
        t["sobelAvg3x3"] = min_max_avg(s, NINE)[2]
        # Model IDs: other-model pixels among the 9, divided by 9.
        ids = frame["object_id"]
        t["modelAverage"] = sum((tap(ids, dx, dy) != ids).astype(D) for dx, dy in NINE) / 9.0
        # Depth pseudo-variances.
        dmin, dmax, davg = min_max_avg(z, NINE)
        mdd = np.minimum(np.abs(dmin - davg), np.abs(dmax - davg))
        on = (mdd >= float(p.depth_threshold)) & (mdd > 0)
        safe = np.where(on, mdd, 1.0)
        t["depthPV"] = np.where(on, (np.abs(z - davg) / safe) ** 2, 0.0)
        t["depthTPV"] = np.where(on, (np.abs(zprev - davg) / safe) ** 4, 0.0)
        t["sobelAvg"] = mix(t["sobelAvgCross"], t["sobelAvg3x3"],
                            np.clip(t["modelAverage"] + t["sobel"], 0, 1))
        t["aliasedValue"] = np.clip(t["sobelAvg"] + t["depthPV"] + t["depthTPV"]
                                    + t["modelAverage"], 0, 1)
        return t["aliasedValue"]
