"""Plain-NumPy float64 reference of two FSR 2 passes: RCAS (robust contrast-adaptive sharpening)
and the upsample (the current frame's Lanczos-2 reconstruction at the output resolution).

Transcribed by hand from AMD's published FidelityFX Super Resolution 2 shaders (GPUOpen,
FidelityFX-FSR2 v2.2.1, MIT licence): `FsrRcasF` in ffx_fsr1.h as the RCAS pass
(ffx_fsr2_rcas.h) includes it, and `ComputeUpsampledColorAndWeight` in ffx_fsr2_upsample.h with
the rectification box of ffx_fsr2_common.h. Per-pixel loops and explicit formulas, independent of
taa_impl's Dr.Jit kernels. Exact reciprocals and the exact Lanczos-2 (the shaders' "reference"
Lanczos type) stand for the GPU's approximations.

Each function has the FSR 2 form and, behind a switch, the study's documented departures from it
(taa_impl.fsr2's module notes: RCAS's limiters, the upsample's off-screen samples), so the Dr.Jit
implementation is checked against this reference exactly where it follows FSR 2 and is seen to
depart only where it says it does.
"""
from __future__ import annotations

import math

import numpy as np

RCAS_LIMIT = 0.25 - 1.0 / 16.0       # FSR_RCAS_LIMIT: "the limit of providing unnatural results"
FSR2_EPSILON = 1e-3                  # ffx_fsr2_common.h


def _tap(img, dx, dy):
    h, w = img.shape[:2]
    ys, xs = np.indices((h, w))
    return img[np.clip(ys + dy, 0, h - 1), np.clip(xs + dx, 0, w - 1)]


def rcas(img, stops: float, centre_in_limiters: bool = True, denoise: bool = False) -> np.ndarray:
    """RCAS of an (H, W, 3) image in [0, 1], sharpness `stops` (0 = strongest; each stop halves).

    The cross b (up), d (left), e (centre), f (right), h (down). Per channel, where the lobe w
    would make the output (w (b + d + f + h) + e) / (4 w + 1) leave [0, 1]: w = -min / (4 max)
    and w = (1 - max) / (4 min - 4), with the ring's min and max standing for the taps; the lobe
    is the largest of the channels' max(-hitMin, hitMax), limited to [-RCAS_LIMIT, 0], times
    2^-stops. FSR 2's copy of FsrRcasF uses the ring's min and max alone
    (`centre_in_limiters=False`); FSR 1.0's RCAS, which the study keeps, takes the centre into
    them (min(ring, e), max(ring, e)). `denoise`: FSR 2's FSR_RCAS_DENOISE noise term."""
    img = np.asarray(img, np.float64)
    b, d, f, h = _tap(img, 0, -1), _tap(img, -1, 0), _tap(img, 1, 0), _tap(img, 0, 1)
    e = img
    out = np.empty_like(img)
    for y in range(img.shape[0]):
        for x in range(img.shape[1]):
            ring = np.array([b[y, x], d[y, x], f[y, x], h[y, x]])       # (4, 3)
            mn4, mx4 = ring.min(0), ring.max(0)
            lo = np.minimum(mn4, e[y, x]) if centre_in_limiters else mn4
            hi = np.maximum(mx4, e[y, x]) if centre_in_limiters else mx4
            lobes = []
            for k in range(3):
                hit_min = lo[k] / (4.0 * mx4[k]) if mx4[k] > 0 else 0.0
                hit_max = (1.0 - hi[k]) / (4.0 * mn4[k] - 4.0) if mn4[k] < 1 else 0.0
                lobes.append(max(-hit_min, hit_max))
            lobe = max(-RCAS_LIMIT, min(max(lobes), 0.0)) * 2.0 ** -stops
            if denoise:
                luma2 = [0.5 * p[2] + (0.5 * p[0] + p[1]) for p in (b[y, x], d[y, x], e[y, x], f[y, x], h[y, x])]
                bl, dl, el, fl, hl = luma2
                rng = max(luma2) - min(luma2)
                nz = min(abs(0.25 * (bl + dl + fl + hl) - el) / rng, 1.0) if rng > 0 else 0.0
                lobe *= 1.0 - 0.5 * nz
            out[y, x] = (lobe * (b[y, x] + d[y, x] + f[y, x] + h[y, x]) + e[y, x]) / (4.0 * lobe + 1.0)
    return out


def lanczos2(x: float) -> float:
    """sinc(x) sinc(x / 2) for |x| < 2, else 0; 1 near 0 (FSR 2's Lanczos2, its EPSILON)."""
    x = min(abs(x), 2.0)
    if x < FSR2_EPSILON:
        return 1.0
    return math.sin(math.pi * x) / (math.pi * x) * math.sin(0.5 * math.pi * x) / (0.5 * math.pi * x)


def upsample(img, out_w: int, out_h: int, jitter, kernel_bias, curve_bias, offscreen: str = "zero") -> dict:
    """FSR 2.2.1's `ComputeUpsampledColorAndWeight` (ffx_fsr2_upsample.h) on the current frame
    (H, W, 3), render resolution, at (out_h, out_w). `jitter`: each render sample's position minus
    its pixel centre, in render pixels (FSR 2's Jitter() is its negative: the sample at
    i + 0.5 - Jitter()). `kernel_bias`, `curve_bias`: scalars or (out_h, out_w) arrays.

    Per output pixel, the output centre u in render pixels (as FSR 2 computes it: float32
    (x + 0.5) * render / output size) and the nine samples i in floor(u) + {-1, 0, 1}^2 (FSR 2's
    offsetTL and row/column flips reorder them, they do not move them); offset d = sample - u:
     - colour: sum of Lanczos-2(|d| kernel_bias) c over the on-screen samples; the weight sum
       zeroed at or below FSR2_EPSILON; above it the colour is normalised and deringed: clamped
       into the aabb (its Deringing); at or below it the unnormalised sum is returned;
     - the rectification box over all nine samples, weights exp(curve_bias |d|^2): centre and
       std (`vec`) of the weighted moments (the weight sum taken as 1 at or below FSR2_EPSILON),
       aabb = min/max. FSR 2 loads the samples through ClampLoad with a zero offset, which clamps
       nothing: an off-screen sample is an out-of-range texture load, 0 in Direct3D 12 (and with
       Vulkan's robust image access). `offscreen`: 'zero' reads them so (FSR 2);
       'skip' leaves them out of the box and aabb (the study's departure, taa_impl.fsr2).

    Returns a dict of (out_h, out_w[, 3]) float64 arrays: colour, weight, centre, vec, aabb_min,
    aabb_max."""
    if offscreen not in ("zero", "skip"):
        raise ValueError(f"offscreen must be 'zero' or 'skip', got {offscreen!r}")
    img = np.asarray(img, np.float64)
    rh, rw = img.shape[:2]
    sx, sy = np.float32(rw / out_w), np.float32(rh / out_h)
    kb = np.broadcast_to(np.asarray(kernel_bias, np.float64), (out_h, out_w))
    cb = np.broadcast_to(np.asarray(curve_bias, np.float64), (out_h, out_w))
    res = {k: np.zeros((out_h, out_w, 3)) for k in ("colour", "centre", "vec", "aabb_min", "aabb_max")}
    res["weight"] = np.zeros((out_h, out_w))
    for y in range(out_h):
        for x in range(out_w):
            ux, uy = float(np.float32(x + 0.5) * sx), float(np.float32(y + 0.5) * sy)
            ix, iy = math.floor(ux), math.floor(uy)
            acc, wsum = np.zeros(3), 0.0
            m1, m2, bw = np.zeros(3), np.zeros(3), 0.0
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for yi in (iy - 1, iy, iy + 1):
                for xi in (ix - 1, ix, ix + 1):
                    on = 0 <= xi < rw and 0 <= yi < rh
                    c = img[yi, xi] if on else np.zeros(3)
                    ox = xi + 0.5 + jitter[0] - ux
                    oy = yi + 0.5 + jitter[1] - uy
                    w = lanczos2(math.hypot(ox, oy) * kb[y, x]) if on else 0.0
                    acc += w * c
                    wsum += w
                    if on or offscreen == "zero":
                        bwi = math.exp(cb[y, x] * (ox * ox + oy * oy))
                        m1 += bwi * c
                        m2 += bwi * c * c
                        bw += bwi
                        lo, hi = np.minimum(lo, c), np.maximum(hi, c)
            if abs(bw) <= FSR2_EPSILON:
                bw = 1.0
            centre = m1 / bw
            res["centre"][y, x] = centre
            res["vec"][y, x] = np.sqrt(np.abs(m2 / bw - centre * centre))
            res["aabb_min"][y, x], res["aabb_max"][y, x] = lo, hi
            if wsum > FSR2_EPSILON:
                res["colour"][y, x] = np.clip(acc / wsum, lo, hi)
                res["weight"][y, x] = wsum
            else:
                res["colour"][y, x] = acc
    return res
