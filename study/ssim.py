"""SSIM in Dr.Jit (float64): the per-channel form the study reports and MATLAB's volume form the
thesis used, computed together from one pair of separable passes.

Per-channel (scikit-image 0.26.0 structural_similarity, gaussian_weights=True, sigma 1.5,
use_sample_covariance=False, data_range 255, K1 0.01, K2 0.03): each channel filtered by an 11-tap
Gaussian (truncate 3.5: radius int(3.5 sigma + 0.5) = 5) with scipy.ndimage 'reflect' borders; the
map is the channel mean of the SSIM maps; the scalar is the mean over channels of each map's mean
with the 5-pixel border cropped.

Volume (MATLAB `ssim` as shipped 2017-2018, on an H x W x 3 array): a 3-D Gaussian, sigma 1.5 on
all three axes, filter size 2*ceil(3 sigma)+1 = 11 (ssim.m passes FilterSize itself; imgaussfilt3's
own default 2*ceil(2 sigma)+1 = 7 does not apply), 'replicate' padding on all three axes,
C1 = (0.01 L)^2, C2 = (0.03 L)^2, C3 = C2/2 and exponents 1 (so Wang et al.'s eq. 13), L = 255 for
uint8; ssimval = mean of the map over all H*W*3 voxels, borders included. Along the channel axis
(3 samples, radius 5, replicate) the Gaussian reduces to a fixed 3x3 mixing of the channels, which
commutes with the spatial filter.
"""
from __future__ import annotations

import math

import numpy as np

from . import jit_filter as jf

SIGMA = 1.5
K1, K2 = 0.01, 0.03
DATA_RANGE = 255.0
SKIMAGE_TRUNCATE = 3.5


def skimage_radius(sigma: float = SIGMA) -> int:
    return int(SKIMAGE_TRUNCATE * sigma + 0.5)


def matlab_radius(sigma: float = SIGMA) -> int:
    return int(math.ceil(3 * sigma))


def channel_mixing(weights: np.ndarray, channels: int = 3) -> np.ndarray:
    """M[c, c'] = weight the 1-D filter along the channel axis ('replicate' padding) gives channel
    c' in output channel c."""
    r = len(weights) // 2
    m = np.zeros((channels, channels))
    for c in range(channels):
        for k in range(-r, r + 1):
            m[c, jf.border_index(c + k, channels, "clamp")] += weights[k + r]
    return m


def _check(ref8: np.ndarray, x8: np.ndarray, radius: int) -> None:
    if ref8.shape != x8.shape or ref8.ndim != 3 or ref8.shape[2] != 3:
        raise ValueError(f"SSIM needs two H x W x 3 images of one shape, got {ref8.shape} and {x8.shape}")
    h, w = ref8.shape[:2]
    if min(h, w) < 2 * radius + 1:
        raise ValueError(f"SSIM needs images of at least {2 * radius + 1}x{2 * radius + 1} pixels, got {w}x{h}")


def _ssim_formula(ux, uy, uxx, uyy, uxy, c1, c2):
    vx = uxx - ux * ux
    vy = uyy - uy * uy
    vxy = uxy - ux * uy
    return ((2.0 * ux * uy + c1) * (2.0 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))


def ssim_both(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA, volume: bool = True):
    """(per-channel mean SSIM, its map (H, W) float64, volume SSIM or None)."""
    rc = skimage_radius(sigma)
    _check(ref8, x8, rc)
    h, w = ref8.shape[:2]
    lay = jf.Layout(h, w)
    prec = "float64"
    planes = []
    for c in range(3):
        planes += [lay.upload(ref8[..., c], prec), lay.upload(x8[..., c], prec)]

    def quantities(v):
        q = []
        for c in range(3):
            a, b = v[2 * c], v[2 * c + 1]
            q += [a, b, a * a, b * b, a * b]
        return q

    wc = tuple(float(t) for t in jf.gaussian_weights(sigma, rc))
    filters = [jf.Filter(i, wc, "reflect") for i in range(15)]
    if volume:
        rv = matlab_radius(sigma)
        wv_np = jf.gaussian_weights(sigma, rv)
        wv = tuple(float(t) for t in wv_np)
        mix = channel_mixing(wv_np)
        filters += [jf.Filter(i, wv, "clamp") for i in range(15)]
    hs = jf.hpass(lay, planes, quantities, filters, prec)
    c1, c2 = (K1 * DATA_RANGE) ** 2, (K2 * DATA_RANGE) ** 2

    def finish(f):
        s = None
        for c in range(3):
            sc = _ssim_formula(*f[5 * c:5 * c + 5], c1, c2)
            s = sc if s is None else s + sc
        out = [s * (1.0 / 3.0)]
        if volume:
            v = f[15:]
            tot = None
            for c in range(3):
                mixed = []
                for qi in range(5):
                    acc = None
                    for cc in range(3):
                        if mix[c, cc] != 0:
                            t = v[5 * cc + qi] * float(mix[c, cc])
                            acc = t if acc is None else acc + t
                    mixed.append(acc)
                sc = _ssim_formula(*mixed, c1, c2)
                tot = sc if tot is None else tot + sc
            out.append(tot)
        return out

    vs = jf.vpass(lay, hs, [jf.Filter(i, f.weights, f.border) for i, f in enumerate(filters)], prec)
    res = finish(vs)
    smap = lay.download(res[0])
    mean = float(smap[rc:h - rc, rc:w - rc].mean(dtype=np.float64))
    vol = float(lay.download(res[1]).mean(dtype=np.float64) / 3.0) if volume else None
    return mean, smap, vol


def ssim(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA) -> tuple[float, np.ndarray]:
    mean, smap, _ = ssim_both(ref8, x8, sigma, volume=False)
    return mean, smap


def ssim_volume(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA) -> float:
    return ssim_both(ref8, x8, sigma, volume=True)[2]
