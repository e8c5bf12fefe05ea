"""Converged references: every pixel's display-domain standard error below a bound (issue 9).

A pixel's value is the plain mean of all its samples; its standard error (SE) comes from the
spread of independent estimates, in linear HDR and, through the Jacobian of the display
transform at the mean (spec section 8, channels' covariance kept), in display units: the
transform of the current mean, re-derived after every round, so that the bound holds in the
display domain of the converged image, the one the study judges in. The bound is on the worst
channel, 0.5 LSB of 8 bits by default.

1. Pilot: `min_passes` independent sets of `spp_per_pass` samples at every pixel (the cache uses
   4 x 2), each an Owen-scrambled Sobol' net over the pixel with a scramble of its own
   (references/tracer.py), traced through the Mitsuba sensor and BVH with
   `shading.trace_visible` and `shading.shade` (the raster's function); transport 'path' calls
   Mitsuba's path integrator per ray the same way (its other dimensions from an independent
   sampler). The spread of the sets is the pilot's noise estimate; each pixel also keeps its
   smallest and largest sample, per channel, over everything it is ever given.
2. The unseen-feature floor. A pixel whose samples all missed a sliver of another surface shows
   no variance, however bright the sliver. But such a sliver usually shows next door (an edge,
   a thin line, a texel boundary, a shadow continues into a neighbour), so every pixel whose 3x3
   window holds sample values lo..hi gets a floor on its SE: the display-domain error if one of
   its M samples had been lo or hi, i.e. |encode(mean + (c - mean) / M) - encode(mean)| for
   c = lo, hi (a feature of 1/M of the pixel, which M samples miss with probability ~ 1/e; the
   same size as the SE one such hit would give). It falls as 1/M, so the pixel is refined until
   M ~ (contrast / bound): on a black background next to white, ~1e4 samples. A pixel claims
   SE 0 only when every sample in its window had one value. The reported SE is the larger of
   the floor and the spread of the samples (`display_floor` keeps the floor). Values, not hit
   primitives or objects, decide: the floor needs the contrast, and a change of triangle or
   object with no change of value (a smooth mesh, glTF primitives of one material) needs none.
3. Rounds: every pixel whose pilot samples vary (the spread of 4 sets is a rough estimate)
   and every pixel over the bound gets R = `replicates` independent sets of `_FIRST_MIN` ..
   `_FIRST_MAX` samples, then rounds: pixels over the bound get one more set per replicate, of a
   power of two near what they ask for, 1.2 M (se / bound)^2 - M for the spread (SE ~ 1/sqrt(M)
   if stratification does not help, so a ceiling) or 1.2 M (floor / bound) - M for the floor, at
   most 3x the replicate's size so a poor estimate is refreshed before much is spent. After
   each round the floors of the refined pixels and their neighbours are recomputed from the new
   extremes, so a sliver found in one pixel is followed into the next (region growing). All R
   replicates of a pixel hold the same count, so mean = (M_p pilot mean + R m replicate mean) / M,
   the plain mean, and cov = ((M_p / M)^2 cov_pilot + (R m / M)^2 cov_replicates), the latter
   with R - 1 degrees of freedom however the samples inside a replicate are stratified.
4. Rounds stop when every pixel meets the bound or holds `max_spp`; pixels still over it are
   counted (`over_bound`), never hidden. If the mean noise (the secondary figure,
   10 log10(1 / mean SE^2)) is still below `target_noise_db`, the bound is tightened.

Why stopping on the data leaves the mean (almost) unbiased: each round's new samples are
independent of everything drawn before and have mean mu, so for a pixel's sample sum S and count
M (a stopping time: each decision uses only samples already drawn) Wald's identities give
E[S - M mu] = 0 and E[(S - M mu)^2] = E[sum of the rounds' variances]. The plain mean's bias is
E[(S - M mu)(1/M - E[1/M])], so by Cauchy-Schwarz
    |E[S / M] - mu| <= sqrt(E[(S - M mu)^2]) sd(1/M)  ~  SE x (coefficient of variation of M),
a fraction of the pixel's own SE, which the bound keeps below 0.5 LSB; M varies little between
seeds because the last decision is made from at least a quarter of the final count.
tests/test_reference_adaptive.py measures the result against uniform 16384- and 65536-spp
references (an edge scene, 0.05-px white slivers on black) and the reported SE against a second
seed. What no rule that looks only at samples sees: a feature well under 1/8 of a pixel (the
pilot's reach) whose neighbours show nothing of it either, e.g. an isolated sub-pixel dot, or a
thin object between two surfaces of one colour along its whole length.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

import backend  # noqa: F401  (libLLVM and the Mitsuba variant before anything traces)
from display import DisplayTransform
from scenes import ResolvedScene
from shading import frame_geometry

from . import settings as S
from .mitsuba_scene import path_integrator, path_scene
from .tracer import _PixelTracer

LSB = 1.0 / 255.0
_MARGIN = 1.2            # extra samples planned beyond the predicted count
_GROWTH = 4              # at most this many times a pixel's samples after one round
_FIRST_MIN = 2           # samples per replicate, at least, in a pixel's first set (64 with 32)
_FIRST_MAX = 32          # and at most, as the pilot's own noise estimate is rough


class ReferenceError(RuntimeError):
    pass


@dataclass
class Reference:
    image: np.ndarray        # (H, W, 3) float32 linear HDR, mean over all samples
    stderr: np.ndarray       # (H, W, 3) float32 per-pixel standard error of the mean (linear)
    spp: int                 # mean samples per pixel, rounded
    passes: int              # uniform pilot passes
    seconds: float
    noise_psnr_db: float     # secondary: display-domain noise of the mean, as PSNR
    key: str = ""            # content hash the cache filed it under
    spp_map: np.ndarray | None = None          # (H, W) samples per pixel
    display_stderr: np.ndarray | None = None   # (H, W, 3) display-domain SE (1 = full scale)
    bound_lsb: float = S.SE_BOUND_LSB          # the per-pixel bound it was rendered to
    rounds: int = 0                            # adaptive rounds after the pilot
    display_floor: np.ndarray | None = None    # (H, W, 3) the unseen-feature part of display_stderr
    half_delta: np.ndarray | None = None       # (H, W, 3) linear: half A = image + delta, B = image - delta
    spp_needed: int = 0     # what the worst pixel over the bound at the cap would take (0: none)
    _history: list = field(default_factory=list, repr=False)

    @property
    def noise_history(self):
        """(mean spp, seconds, noise PSNR dB, max SE LSB) after each pass or round."""
        return self._history

    def halves(self) -> tuple[np.ndarray, np.ndarray]:
        """The two independent half-sample references (linear HDR) whose mean is `image`: what a
        figure's reference uncertainty is estimated from (study.metrics.uncertainty)."""
        if self.half_delta is None:
            raise ReferenceError("this reference keeps no half-sample split")
        return self.image + self.half_delta, self.image - self.half_delta

    @property
    def se_lsb(self) -> np.ndarray:
        """(H, W) display-domain SE of the worst channel, in 8-bit LSB."""
        return self.display_stderr.max(axis=-1) / LSB

    @property
    def spp_mean(self) -> float:
        return float(self.spp_map.mean())

    @property
    def spp_max(self) -> int:
        return int(self.spp_map.max())

    @property
    def se_p999_lsb(self) -> float:
        return float(np.percentile(self.se_lsb, 99.9))

    @property
    def se_max_lsb(self) -> float:
        return float(self.se_lsb.max())

    @property
    def floor_bound(self) -> int:
        """Pixels whose reported SE is the unseen-feature floor, not the spread of their samples."""
        if self.display_floor is None:
            return 0
        return int(np.sum(np.any((self.display_floor >= self.display_stderr) & (self.display_stderr > 0), axis=-1)))

    @property
    def over_bound(self) -> int:
        """Pixels whose SE is still above the bound (they hit the sample cap)."""
        return int(np.sum(self.se_lsb > self.bound_lsb * (1 + 1e-5)))   # float32 storage slack


def _cov_of_mean(reps: np.ndarray) -> np.ndarray:
    """(K, 3, 3) covariance of the mean of K sets of R independent estimates reps (K, R, 3)."""
    r = reps.shape[1]
    dev = reps - reps.mean(axis=1, keepdims=True)
    return np.einsum("kri,krj->kij", dev, dev) / ((r - 1) * r)


class _Estimates:
    """Per pixel: the pilot's mean and its covariance (from the spread of its passes), and for
    the pixels that get more samples, R replicate sums (`slot` maps a pixel to its row). A pixel's
    mean is the plain mean of all its samples; `cov` is the covariance of that mean."""

    def __init__(self, pilot: np.ndarray, spp_per_pass: int, replicates: int):
        """pilot (npix, K, 3): K independent pilot estimates (means of spp_per_pass samples)."""
        npix, k = pilot.shape[:2]
        self.r = replicates
        self.mp = k * spp_per_pass                    # pilot samples per pixel
        self.pilot_mean = pilot.mean(axis=1, dtype=np.float64)
        self.pilot_cov = np.zeros((npix, 3, 3))
        self.varies = np.flatnonzero(np.any(pilot.max(axis=1) != pilot.min(axis=1), axis=-1))
        self.pilot_cov[self.varies] = _cov_of_mean(pilot[self.varies].astype(np.float64))
        self.mean, self.cov = self.pilot_mean.copy(), self.pilot_cov.copy()
        self.pilot_half = pilot[:, :k // 2].mean(axis=1, dtype=np.float64)   # passes 0..K/2-1
        self.m = np.zeros(npix, np.int64)             # samples per replicate after the pilot
        self.slot = np.full(npix, -1, np.int64)
        self.sums = np.zeros((0, replicates, 3))

    @property
    def spp(self) -> np.ndarray:
        return self.mp + self.r * self.m

    def add(self, pix: np.ndarray, a: int, sums: np.ndarray) -> None:
        """sums (K, R, 3): each replicate's sum over its a new samples, for pixels pix."""
        new = pix[self.slot[pix] < 0]
        if len(new):
            self.slot[new] = len(self.sums) + np.arange(len(new))
            self.sums = np.concatenate([self.sums, np.zeros((len(new), self.r, 3))])
        rows = self.slot[pix]
        self.sums[rows] += sums
        self.m[pix] += a
        reps = self.sums[rows] / self.m[pix, None, None]
        ma = (self.r * self.m[pix]).astype(np.float64)
        w = (ma / (self.mp + ma))[:, None]           # the replicates' share of the samples
        self.mean[pix] = (1 - w) * self.pilot_mean[pix] + w * reps.mean(axis=1)
        self.cov[pix] = ((1 - w) ** 2)[:, :, None] * self.pilot_cov[pix] + (w ** 2)[:, :, None] * _cov_of_mean(reps)

    def half_delta(self) -> np.ndarray:
        """(npix, 3) A - mean, where A is the plain mean of one half of every pixel's samples (the
        first K/2 pilot passes and the first R/2 replicates) and B, the other half, is 2 mean - A.
        A and B are independent estimates of the pixel, each with twice the mean's variance."""
        a = self.pilot_half * (self.mp / 2)
        rows = np.flatnonzero(self.slot >= 0)
        a[rows] += self.sums[self.slot[rows], : self.r // 2].sum(axis=1)
        return a / (self.spp[:, None] / 2) - self.mean

    def linear_se(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diagonal(self.cov, axis1=1, axis2=2), 0.0))


def _display_se(disp: DisplayTransform, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """SE of the display value of the mean, per channel: sqrt(J cov J^T), J at the mean."""
    base = disp.encode(mean)
    jac = np.empty((len(mean), 3, 3))
    for k in range(3):   # forward differences: the tone map is clamped at 0, so stay on its right
        h = 1e-7 + 1e-5 * np.abs(mean[:, k])
        x = mean.copy()
        x[:, k] += h
        jac[:, :, k] = (disp.encode(x) - base) / h[:, None]
    var = np.einsum("pck,pkl,pcl->pc", jac, cov, jac)
    return np.sqrt(np.maximum(var, 0.0))


def _dilate(mask: np.ndarray) -> np.ndarray:
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    col = out.copy()
    out[:, 1:] |= col[:, :-1]
    out[:, :-1] |= col[:, 1:]
    return out


def _window(a: np.ndarray, op) -> np.ndarray:
    """op (np.minimum / np.maximum) over each pixel's 3x3 window of a (H, W, C), edges clamped."""
    out = a.copy()
    out[1:] = op(out[1:], a[:-1])
    out[:-1] = op(out[:-1], a[1:])
    col = out.copy()
    out[:, 1:] = op(out[:, 1:], col[:, :-1])
    out[:, :-1] = op(out[:, :-1], col[:, 1:])
    return out


def _unseen_floor(disp: DisplayTransform, mean: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(display, linear) per-channel floor on the SE of pixels whose 3x3 window holds sample
    values lo..hi: the error if one of the pixel's m samples had been such a value, i.e. a
    feature covering 1/m of it that every sample missed (see the module docstring)."""
    base = disp.encode(mean)
    up, down = (hi - mean) / m[:, None], (lo - mean) / m[:, None]
    d = np.maximum(np.abs(disp.encode(mean + up) - base), np.abs(disp.encode(mean + down) - base))
    return d, np.maximum(np.abs(up), np.abs(down))


def _samples_needed(spp: np.ndarray, se_spread: np.ndarray, se_floor: np.ndarray, bound: float) -> np.ndarray:
    """Samples for the bound: SE ~ 1/sqrt(M) for the spread (a ceiling), ~ 1/M for the floor."""
    return np.maximum(spp * (se_spread / bound) ** 2, spp * (se_floor / bound))


def _noise_db(dse: np.ndarray) -> float:
    mse = float(np.mean(dse ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)


def render_reference(scene: ResolvedScene, t: int, width: int, height: int, *,
                     se_bound_lsb: float = S.SE_BOUND_LSB, target_noise_db: float = S.TARGET_NOISE_DB, spp_per_pass: int = 4,
                     min_passes: int = 4, replicates: int = 32, max_spp: int = 1 << 16, seed: int = 0,
                     progress: Callable[[int, float], None] | None = None) -> Reference:
    """Reference of frame t: a pilot of `min_passes` sets of `spp_per_pass` at every pixel, then
    rounds of `replicates` independent sets per pixel that needs them (see the module docstring)."""
    if min_passes < 2 or replicates < 2 or min_passes % 2 or replicates % 2:
        raise ReferenceError(f"min_passes and replicates must be even and >= 2 (the noise is estimated "
                             f"from them, and the reference is split into two halves), got {min_passes}, {replicates}")
    if se_bound_lsb <= 0 or spp_per_pass < 1 or spp_per_pass & (spp_per_pass - 1):
        raise ReferenceError(f"se_bound_lsb must be > 0 and spp_per_pass a power of two (a set is a whole "
                             f"Sobol' net), got {se_bound_lsb}, {spp_per_pass}")
    cam = scene.camera(t, width, height)
    path = scene.desc.transport == "path"
    if path and any(a is not None for a in scene.alphas):
        # Mitsuba's path tracer tests shadow rays with ray_test, which sees a masked surface as
        # opaque, and spends a bounce on each cut-out crossed: the reference would be wrong.
        raise ReferenceError(f"scene {scene.name!r}: transport 'path' does not support alpha cut-outs "
                             "(Mitsuba's path tracer treats masked surfaces as opaque to shadow rays); "
                             "use direct_shadows")
    geo = mscene = integ = None
    if path:
        mscene, integ = path_scene(scene, t), path_integrator(scene.desc.path_max_depth)
    else:
        geo = frame_geometry(scene, t)
    npix, r = width * height, replicates
    start = time.perf_counter()
    history = []

    def record(est, dse):
        db = _noise_db(dse)
        spp = float(est.spp.mean())
        history.append((spp, time.perf_counter() - start, db, float(dse.max() / LSB)))
        if progress:
            progress(int(round(spp)), db)

    tracer = _PixelTracer(scene, cam, path, mscene, integ, geo)
    # Pilot: min_passes independent sets (nets) of spp_per_pass at every pixel, which also
    # give each pixel's smallest and largest sample (the unseen-feature floor below).
    pilot = np.empty((npix, min_passes, 3), np.float32)
    lo, hi = np.empty((npix, 3)), np.empty((npix, 3))
    for g, sums, glo, ghi in tracer.chunked(np.arange(npix), min_passes, spp_per_pass,
                                            np.random.default_rng([seed, 8])):
        if not np.all(np.isfinite(sums)):
            raise ReferenceError(f"scene {scene.name!r} frame {t}: the pilot produced NaN/Inf")
        pilot[g], lo[g], hi[g] = sums / spp_per_pass, glo, ghi
    est = _Estimates(pilot, spp_per_pass, r)
    del pilot
    # the current mean's transform, re-derived every round: one pass of a few samples can be far
    # off (thin bright lines on black: 4.4x the exposure), and the bound must hold in the study's
    disp = DisplayTransform.from_reference(est.mean.reshape(height, width, 3))
    dse_s = np.zeros((npix, 3))           # from the spread of the samples
    dse_s[est.varies] = _display_se(disp, est.mean[est.varies], est.cov[est.varies])
    floor_d, floor_l = np.zeros((npix, 3)), np.zeros((npix, 3))

    def update_floor(where: np.ndarray):
        wlo = _window(lo.reshape(height, width, 3), np.minimum).reshape(npix, 3)[where]
        whi = _window(hi.reshape(height, width, 3), np.maximum).reshape(npix, 3)[where]
        floor_d[where], floor_l[where] = _unseen_floor(disp, est.mean[where], wlo, whi, est.spp[where])

    def contrast() -> np.ndarray:          # pixels whose 3x3 window holds more than one value
        return np.flatnonzero(np.any(_window(hi.reshape(height, width, 3), np.maximum) >
                                     _window(lo.reshape(height, width, 3), np.minimum), axis=-1).ravel())

    update_floor(contrast())
    dse = np.maximum(dse_s, floor_d)
    record(est, dse)

    cap = max((max_spp - est.mp) // r, 1)         # samples per replicate
    bound = se_bound_lsb * LSB
    target_mse = 10 ** (-target_noise_db / 10)
    rounds = tightened = 0
    while True:
        worst_s, worst_f = dse_s.max(axis=-1), floor_d.max(axis=-1)
        worst = np.maximum(worst_s, worst_f)
        over = (worst > bound) & (est.m < cap)
        spp = est.spp
        need = _samples_needed(spp, worst_s, worst_f, bound) * _MARGIN
        want = (np.ceil(need) - spp) / r      # per replicate
        if rounds == 0:
            # A pilot spread of min_passes estimates is a rough noise estimate: every pixel
            # whose samples vary gets one set of replicates (R - 1 degrees of freedom).
            over[est.varies] = True
        if not over.any():
            mse = float(np.mean(dse ** 2))
            improvable = np.any((worst > 0) & (est.m < cap))
            if mse <= target_mse or not improvable or tightened >= 20:
                break
            # The mean-noise target binds: tighten the per-pixel bound by what it misses.
            bound *= max(math.sqrt(target_mse / mse), 0.25)
            tightened += 1
            continue
        pix = np.flatnonzero(over)
        m = est.m[pix]
        # a power of two (one whole net); the first set _FIRST_MIN.._FIRST_MAX,
        # later ones at most 3 m; never past the cap
        most = np.where(m == 0, _FIRST_MAX, 2 ** np.floor(np.log2(np.maximum((_GROWTH - 1) * m, 1))))
        add = np.minimum(2 ** np.ceil(np.log2(np.maximum(want[pix], np.where(m == 0, _FIRST_MIN, 1)))), most)
        # never past the cap: a set's size stays a power of two (a whole net)
        add = (2 ** np.floor(np.log2(np.minimum(add, cap - m)))).astype(np.int64)
        rng = np.random.default_rng([seed, 9, rounds])
        for a in np.unique(add):          # one set size per group of pixels
            for g, sums, glo, ghi in tracer.chunked(pix[add == a], r, int(a), rng):
                if not np.all(np.isfinite(sums)):
                    raise ReferenceError(f"scene {scene.name!r} frame {t}: round {rounds} produced NaN/Inf")
                est.add(g, int(a), sums)
                lo[g], hi[g] = np.minimum(lo[g], glo), np.maximum(hi[g], ghi)
        dse_s[pix] = _display_se(disp, est.mean[pix], est.cov[pix])
        # the floor moves where a pixel or a neighbour got samples (new extremes, or more samples)
        touched = np.zeros(npix, bool)
        touched[pix] = True
        update_floor(np.flatnonzero(_dilate(touched.reshape(height, width)).ravel()))
        now = DisplayTransform.from_reference(est.mean.reshape(height, width, 3))
        if now != disp:                   # (to 3 digits) every pixel's display error moves with it
            disp = now
            noisy = np.flatnonzero(np.any(np.diagonal(est.cov, axis1=1, axis2=2) > 0, axis=-1))
            dse_s[:] = 0.0
            dse_s[noisy] = _display_se(disp, est.mean[noisy], est.cov[noisy])
            update_floor(contrast())
        dse = np.maximum(dse_s, floor_d)
        rounds += 1
        record(est, dse)

    spp_map = est.spp.reshape(height, width)
    b0 = se_bound_lsb * LSB
    missed = dse.max(axis=-1) > b0 * (1 + 1e-5)
    needed = _samples_needed(est.spp, dse_s.max(axis=-1), floor_d.max(axis=-1), b0)[missed]
    lin_se = np.maximum(est.linear_se(), floor_l)
    return Reference(est.mean.reshape(height, width, 3).astype(np.float32),
                     lin_se.reshape(height, width, 3).astype(np.float32),
                     int(round(spp_map.mean())), min_passes, time.perf_counter() - start, _noise_db(dse),
                     spp_map=spp_map.astype(np.int32), display_stderr=dse.reshape(height, width, 3).astype(np.float32),
                     bound_lsb=float(se_bound_lsb), rounds=rounds, _history=history,
                     display_floor=floor_d.reshape(height, width, 3).astype(np.float32),
                     half_delta=est.half_delta().reshape(height, width, 3).astype(np.float32),
                     spp_needed=int(np.ceil(needed.max())) if len(needed) else 0)
