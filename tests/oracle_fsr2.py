"""Plain-NumPy float64 reference of two FSR 2 passes: RCAS (robust contrast-adaptive sharpening)
and the upsample (the current frame's Lanczos-2 reconstruction at the output resolution).

Transcribed by hand from AMD's published FidelityFX Super Resolution 2 shaders (GPUOpen,
FidelityFX-FSR2 v2.2.1, MIT licence): `FsrRcasF` in ffx_fsr1.h as the RCAS pass
(ffx_fsr2_rcas.h) includes it, and `ComputeUpsampledColorAndWeight` in ffx_fsr2_upsample.h with
the rectification box of ffx_fsr2_common.h. Per-pixel loops and explicit formulas, independent of
taa_impl's Dr.Jit kernels. Exact reciprocals and the exact Lanczos-2 (the shaders' "reference"
Lanczos type) stand for the GPU's approximations.

Each function has the FSR 2 form and, behind a switch, the study's documented departures from it
(taa_impl.fsr2's module notes), so the Dr.Jit implementation is checked against this reference
exactly where it follows FSR 2 and is seen to depart only where it says it does.
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


def upsample(img, out_w: int, out_h: int, jitter, kernel_bias, curve_bias, study: bool = True) -> dict:
    """The current frame (H, W, 3), render resolution, at (out_h, out_w): per output pixel, the
    render samples near its centre (jittered positions: pixel centre + `jitter`, render pixels),
    weighted Lanczos-2(|offset| * kernel_bias); the rectification box from the same samples,
    weights exp(curve_bias |offset|^2): its centre, std (`vec`) and min/max. `kernel_bias`,
    `curve_bias`: scalars or (out_h, out_w) arrays.

    FSR 2 (study=False): the 3x3 samples around floor(output centre), box and aabb over all nine
    (clamp-loaded), the colour deringed into the aabb, no weight below FSR2_EPSILON.
    The study (study=True): the 4x4 around the output centre without its corners (12 samples,
    from the sample left of and above the centre), box and aabb over the on-screen ones, deringed
    into the 2x2 nearest samples' range, and the box centre where the weights sum to <= 1e-4.

    Returns a dict of (out_h, out_w[, 3]) float64 arrays: colour, weight, centre, vec, aabb_min,
    aabb_max."""
    img = np.asarray(img, np.float64)
    rh, rw = img.shape[:2]
    sx, sy = rw / out_w, rh / out_h
    kb = np.broadcast_to(np.asarray(kernel_bias, np.float64), (out_h, out_w))
    cb = np.broadcast_to(np.asarray(curve_bias, np.float64), (out_h, out_w))
    res = {k: np.zeros((out_h, out_w, 3)) for k in ("colour", "centre", "vec", "aabb_min", "aabb_max")}
    res["weight"] = np.zeros((out_h, out_w))
    for y in range(out_h):
        for x in range(out_w):
            ux, uy = (x + 0.5) * sx, (y + 0.5) * sy
            if study:
                bx, by = math.floor(ux - 0.5 - jitter[0]), math.floor(uy - 0.5 - jitter[1])
                taps = [(bx + i, by + j, i in (0, 1) and j in (0, 1)) for j in (-1, 0, 1, 2) for i in (-1, 0, 1, 2)
                        if not (i in (-1, 2) and j in (-1, 2))]
            else:
                ix, iy = math.floor(ux), math.floor(uy)
                taps = [(ix + i, iy + j, False) for j in (-1, 0, 1) for i in (-1, 0, 1)]
            acc, wsum = np.zeros(3), 0.0
            m1, m2, bw = np.zeros(3), np.zeros(3), 0.0
            lo, hi, dlo, dhi = [np.full(3, np.inf), np.full(3, -np.inf), np.full(3, np.inf), np.full(3, -np.inf)]
            for xi, yi, near in taps:
                on = 0 <= xi < rw and 0 <= yi < rh
                c = img[min(max(yi, 0), rh - 1), min(max(xi, 0), rw - 1)]
                ox = xi + 0.5 + jitter[0] - ux
                oy = yi + 0.5 + jitter[1] - uy
                w = lanczos2(math.hypot(ox, oy) * kb[y, x]) if on else 0.0
                acc += w * c
                wsum += w
                if on or not study:
                    bwi = math.exp(cb[y, x] * (ox * ox + oy * oy))
                    m1 += bwi * c
                    m2 += bwi * c * c
                    bw += bwi
                    lo, hi = np.minimum(lo, c), np.maximum(hi, c)
                    if near:
                        dlo, dhi = np.minimum(dlo, c), np.maximum(dhi, c)
            if not study and abs(bw) <= FSR2_EPSILON:
                bw = 1.0
            centre = m1 / bw
            res["centre"][y, x] = centre
            res["vec"][y, x] = np.sqrt(np.abs(m2 / bw - centre * centre))
            res["aabb_min"][y, x], res["aabb_max"][y, x] = lo, hi
            if study:
                ok = wsum > 1e-4
                res["colour"][y, x] = np.clip(acc / wsum if ok else centre, dlo, dhi)
                res["weight"][y, x] = wsum if ok else 0.0
            elif wsum > FSR2_EPSILON:
                res["colour"][y, x] = np.clip(acc / wsum, lo, hi)
                res["weight"][y, x] = wsum
            else:
                res["colour"][y, x] = acc
    return res
