"""A reference pixel's estimates: the samples that decide how many more it gets, and the samples
its value is the mean of (references.render's adaptive loop reads and updates them).

Two ways to use the samples (`held_out`):
  - False: every sample both decides and estimates (the plain mean of all of them). A pixel stops
    when its replicates' spread is low, and where the spread moves with the value (hair: fewer
    bright hits, a lower mean and a lower spread) that biases the mean, by a fraction of its own
    SE (measured on hairball_lit at 8 LSB: -0.039 SE over the refined pixels, scripts/reference_bias.py).
  - True: the decisions see only the *deciding* share (the first half of the pilot's passes and the
    first quarter of the replicates, with every other sample count equal) and the value is the mean
    of the rest. The counts are then a function of samples independent of the value's, so the value
    is unbiased in linear HDR, exactly (and so are its two halves, each half of the rest); the
    deciding share's spread predicts the held-out mean's covariance, whose counts are known.
    It costs the deciding quarter's samples; what it buys is figures that do not drift with the
    bound, so the figures' rule can stop where their uncertainty does (study.engine.precision).
"""
from __future__ import annotations

import math

import numpy as np

from display import DisplayTransform


def fold(op, a: np.ndarray, axis: int = -1) -> np.ndarray:
    """`op` (np.maximum, np.minimum, np.logical_or) over a short axis of `a`: the value of
    a.max(axis) / a.min(axis) / np.any(a, axis), exactly, 5-9x faster on a frame's (npix, 3) or
    (npix, passes, 3) arrays (numpy's reduction loops over such an axis innermost, an element at a
    time; this takes whole slices)."""
    parts = np.moveaxis(np.asarray(a), axis, 0)
    out = parts[0].copy()
    for p in parts[1:]:
        op(out, p, out=out)
    return out


def _cov_of_mean(reps: np.ndarray) -> np.ndarray:
    """(K, 3, 3) covariance of the mean of K sets of R independent estimates reps (K, R, 3)."""
    r = reps.shape[1]
    dev = reps - reps.mean(axis=1, keepdims=True)
    # the six distinct products, each a contiguous dot over R: einsum("kri,krj->kij")'s sums in
    # another order (within 1e-12), 2-5x faster (it strides over the 3 channels innermost)
    ch = [np.ascontiguousarray(dev[:, :, i]) for i in range(3)]
    out = np.empty((len(reps), 3, 3))
    for i in range(3):
        for j in range(i, 3):
            out[:, i, j] = np.einsum("kr,kr->k", ch[i], ch[j])
            out[:, j, i] = out[:, i, j]
    return out / ((r - 1) * r)


class Estimates:
    """Per pixel: K pilot passes (means of spp_per_pass samples each) and, for the pixels that get
    more samples, R replicate sums of m samples each (`slot` maps a pixel to its row). `dmean` and
    `dcov` are what decisions read: the deciding samples' mean and the covariance they predict for
    the estimate's mean; `estimate()` is the reference's value and its own covariance."""

    def __init__(self, pilot: np.ndarray, spp_per_pass: int, replicates: int, held_out: bool = False):
        """pilot (npix, K, 3): K independent pilot estimates (means of spp_per_pass samples)."""
        npix, k = pilot.shape[:2]
        r = replicates
        self.r, self.s, self.held_out = r, spp_per_pass, held_out
        self.mp = k * spp_per_pass                    # pilot samples per pixel
        if held_out:
            self.dp, self.ep = slice(0, k // 2), slice(k // 2, k)       # pilot passes
            self.dr, self.er = slice(0, r // 4), slice(r // 4, r)       # replicates
        else:
            self.dp = self.ep = slice(0, k)
            self.dr = self.er = slice(0, r)
        self.kd, self.ke = len(range(k)[self.dp]), len(range(k)[self.ep])
        self.rd, self.re = len(range(r)[self.dr]), len(range(r)[self.er])
        self.pilot = pilot
        pd = pilot[:, self.dp].astype(np.float64)
        self.pilot_dmean = pd.mean(axis=1)
        self.varies = np.flatnonzero(fold(np.logical_or, fold(np.maximum, pd, 1) != fold(np.minimum, pd, 1)))
        # the deciding passes' spread, as the covariance of the estimate's pilot mean (ke passes)
        self.pilot_dcov = np.zeros((npix, 3, 3))
        self.pilot_dcov[self.varies] = _cov_of_mean(pd[self.varies]) * (self.kd / self.ke)
        self.dmean, self.dcov = self.pilot_dmean.copy(), self.pilot_dcov.copy()
        self.m = np.zeros(npix, np.int64)             # samples per replicate after the pilot
        self.slot = np.full(npix, -1, np.int64)
        self._sums, self._rows = np.zeros((0, r, 3)), 0   # grown by doubling: not copied every round

    @property
    def sums(self) -> np.ndarray:
        """(rows, R, 3) each refined pixel's replicate sums (row `slot[pixel]`)."""
        return self._sums[: self._rows]

    @property
    def spp(self) -> np.ndarray:
        """Samples traced per pixel (what the reference cost)."""
        return self.mp + self.r * self.m

    @property
    def spp_estimate(self) -> np.ndarray:
        """Samples the reference's value is the mean of."""
        return self.ke * self.s + self.re * self.m

    def add(self, pix: np.ndarray, a: int, sums: np.ndarray) -> None:
        """sums (K, R, 3): each replicate's sum over its a new samples, for pixels pix."""
        new = pix[self.slot[pix] < 0]
        if len(new):
            self.slot[new] = self._rows + np.arange(len(new))
            self._rows += len(new)
            if self._rows > len(self._sums):
                grown = np.zeros((max(self._rows, 2 * len(self._sums)), self.r, 3))
                grown[: len(self._sums)] = self._sums
                self._sums = grown
        rows = self.slot[pix]
        self._sums[rows] += sums
        self.m[pix] += a
        reps = self.sums[rows, self.dr] / self.m[pix, None, None]
        m = self.m[pix].astype(np.float64)
        wd = (self.rd * m / (self.kd * self.s + self.rd * m))[:, None]   # the replicates' share, deciding
        we = (self.re * m / (self.ke * self.s + self.re * m))[:, None, None]   # and in the estimate
        self.dmean[pix] = (1 - wd) * self.pilot_dmean[pix] + wd * reps.mean(axis=1)
        self.dcov[pix] = (1 - we) ** 2 * self.pilot_dcov[pix] + we ** 2 * _cov_of_mean(reps) * (self.rd / self.re)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """(npix, 3) the reference's value: the plain mean of the estimating samples; (npix, 3, 3)
        its covariance, from their own spread."""
        pe = self.pilot[:, self.ep].astype(np.float64)
        mean = pe.mean(axis=1)
        cov = np.zeros((len(mean), 3, 3))
        vary = np.flatnonzero(fold(np.logical_or, fold(np.maximum, pe, 1) != fold(np.minimum, pe, 1)))
        cov[vary] = _cov_of_mean(pe[vary])
        rows = np.flatnonzero(self.slot >= 0)
        if len(rows):
            m = self.m[rows].astype(np.float64)
            reps = self.sums[self.slot[rows], self.er] / m[:, None, None]
            we = self.re * m / (self.ke * self.s + self.re * m)
            mean[rows] = (1 - we[:, None]) * mean[rows] + we[:, None] * reps.mean(axis=1)
            cov[rows] = (1 - we[:, None, None]) ** 2 * cov[rows] + we[:, None, None] ** 2 * _cov_of_mean(reps)
        return mean, cov

    def half_delta(self, mean: np.ndarray) -> np.ndarray:
        """(npix, 3) A - mean, where A is the plain mean of one half of the estimating samples (the
        first half of its pilot passes and of its replicates) and B, the other half, is 2 mean - A.
        A and B are independent estimates of the pixel, each with twice the mean's variance."""
        pe = self.pilot[:, self.ep].astype(np.float64)
        a = pe[:, : self.ke // 2].sum(axis=1) * self.s
        rows = np.flatnonzero(self.slot >= 0)
        reps = self.sums[self.slot[rows], self.er]
        a[rows] += reps[:, : self.re // 2].sum(axis=1)
        return a / (self.spp_estimate[:, None] / 2) - mean


def linear_se(cov: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))


def display_se(disp: DisplayTransform, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """SE of the display value of the mean, per channel: sqrt(J cov J^T), J at the mean."""
    base = disp.encode(mean)
    jac = np.empty((len(mean), 3, 3))
    for k in range(3):   # forward differences: the tone map is clamped at 0, so stay on its right
        h = 1e-7 + 1e-5 * np.abs(mean[:, k])
        x = mean.copy()
        x[:, k] += h
        jac[:, :, k] = (disp.encode(x) - base) / h[:, None]
    var = ((jac @ cov) * jac).sum(axis=-1)        # J cov J^T's diagonal (einsum: 2x slower)
    return np.sqrt(np.maximum(var, 0.0))


def dilate(mask: np.ndarray) -> np.ndarray:
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    col = out.copy()
    out[:, 1:] |= col[:, :-1]
    out[:, :-1] |= col[:, 1:]
    return out


def window(a: np.ndarray, op) -> np.ndarray:
    """op (np.minimum / np.maximum) over each pixel's 3x3 window of a (H, W, C), edges clamped."""
    out = a.copy()
    op(out[1:], a[:-1], out=out[1:])          # in place: no temporary frame per shift
    op(out[:-1], a[1:], out=out[:-1])
    col = out.copy()
    op(out[:, 1:], col[:, :-1], out=out[:, 1:])
    op(out[:, :-1], col[:, 1:], out=out[:, :-1])
    return out


def unseen_floor(disp: DisplayTransform, mean: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(display, linear) per-channel floor on the SE of pixels whose 3x3 window holds sample
    values lo..hi: the error if one of the pixel's m samples had been such a value, i.e. a
    feature covering 1/m of it that every sample missed (see references.render)."""
    base = disp.encode(mean)
    up, down = (hi - mean) / m[:, None], (lo - mean) / m[:, None]
    d = np.maximum(np.abs(disp.encode(mean + up) - base), np.abs(disp.encode(mean + down) - base))
    return d, np.maximum(np.abs(up), np.abs(down))


def samples_needed(spp: np.ndarray, se_spread: np.ndarray, se_floor: np.ndarray, bound: float) -> np.ndarray:
    """Samples for the bound: SE ~ 1/sqrt(M) for the spread (a ceiling), ~ 1/M for the floor."""
    return np.maximum(spp * (se_spread / bound) ** 2, spp * (se_floor / bound))


def noise_db(dse: np.ndarray) -> float:
    mse = float(np.mean(dse ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)
