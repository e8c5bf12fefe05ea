"""Converged references: every pixel's display-domain standard error below a bound.

A pixel's value is the plain mean of all its samples; its standard error (SE) comes from the
spread of independent estimates, in linear HDR and, through the Jacobian of the display
transform at the mean (display/__init__.py; channels' covariance kept), in display units: the
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

Why stopping on the data biases the mean, and the estimator that does not: each round's new
samples are independent of everything drawn before and have mean mu, so for a pixel's sample sum
S and count M (a stopping time: each decision uses only samples already drawn) Wald's identities
give E[S - M mu] = 0, and the plain mean's bias is E[(S - M mu)(1/M - E[1/M])]: by Cauchy-Schwarz
at most ~ SE x (coefficient of variation of M), a fraction of the pixel's own SE. It is not zero
where the samples' spread moves with their value (a pixel with more bright hair hits, or whose
mean sits on a flatter part of the display curve, stops sooner): measured, -0.039 SE on
hairball_lit at 8 LSB, and the study's jackknifed MSE of a blurred image 1.2 % high
(scripts/reference_bias.py; tests/test_reference_held_out.py shows it on Bernoulli pixels).
`held_out=True` (what the figures' rule renders, study.config.precision) makes every decision
from a deciding share of the samples (half the pilot's passes, a quarter of the replicates,
references.estimates) and reports the mean of the rest, whose counts are then a function of
samples independent of its own: unbiased, exactly, and so are its halves. The per-pixel bound is
then on the held-out mean's SE as the deciding share predicts it, and the reported SE is the
held-out samples' own spread.
`reuse_from` (frame t - 1's reference): the pixels references.reuse finds no moving object nor its
shadow reaches keep that estimate (value, halves, counts, SE, sample extremes) and are not traced;
the rest converge as above, their floors reading the kept neighbours' stored extremes.
tests/test_reference_adaptive.py measures the result against uniform 16384- and 65536-spp
references (an edge scene, 0.05-px white slivers on black) and the reported SE against a second
seed. What no rule that looks only at samples sees: a feature well under 1/8 of a pixel (the
pilot's reach) whose neighbours show nothing of it either, e.g. an isolated sub-pixel dot, or a
thin object between two surfaces of one colour along its whole length.
"""
from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

import backend  # noqa: F401  (libLLVM and the Mitsuba variant before anything traces)
from display import DisplayTransform
from scenes import ResolvedScene
from shading import frame_geometry

from . import estimates as E
from . import settings as S
from .mitsuba_scene import path_integrator, path_scene
from .result import LSB, Reference, ReferenceError
from .reuse import reuse_mask
from .tracer import _PixelTracer

_MARGIN = 1.2            # extra samples planned beyond the predicted count
_GROWTH = 4              # at most this many times a pixel's samples after one round
_FIRST_MIN = 2           # samples per replicate, at least, in a pixel's first set (64 with 32)
_FIRST_MAX = 32          # and at most, as the pilot's own noise estimate is rough
_DRIFT = 0.02            # a reused pixel's display SE may grow this much with the frame's transform


def render_reference(scene: ResolvedScene, t: int, width: int, height: int, *,
                     se_bound_lsb: float = S.SE_BOUND_LSB, target_noise_db: float = S.TARGET_NOISE_DB, spp_per_pass: int = 4,
                     min_passes: int = 4, replicates: int = 32, max_spp: int = 1 << 16, seed: int = 0,
                     held_out: bool = False, progress: Callable[[int, float], None] | None = None,
                     reuse_from: Reference | None = None) -> Reference:
    """Reference of frame t: a pilot of `min_passes` sets of `spp_per_pass` at every pixel, then
    rounds of `replicates` independent sets per pixel that needs them (see the module docstring);
    `held_out`: the value is the mean of samples no decision saw (references.estimates).
    `reuse_from`: frame t - 1's reference, rendered with the same settings: the pixels that
    references.reuse finds no moving object nor shadow reaches keep its estimate, unless it missed
    the bound (it hit the sample cap, or its display SE under this frame's transform is over)."""
    if min_passes < 2 or replicates < 2 or min_passes % 2 or replicates % 2:
        raise ReferenceError(f"min_passes and replicates must be even and >= 2 (the noise is estimated "
                             f"from them, and the reference is split into two halves), got {min_passes}, {replicates}")
    if held_out and (min_passes % 4 or replicates % 8):
        raise ReferenceError(f"held_out needs min_passes a multiple of 4 and replicates of 8 (a deciding share, "
                             f"and two halves of the rest), got {min_passes}, {replicates}")
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
    tracer = _PixelTracer(scene, cam, path, mscene, integ, geo)
    # a frame that keeps an earlier frame's pixels draws scrambles of its own, not that frame's
    kw = dict(se_bound_lsb=se_bound_lsb, target_noise_db=target_noise_db, spp_per_pass=spp_per_pass,
              min_passes=min_passes, replicates=replicates, max_spp=max_spp, held_out=held_out,
              seed=seed if reuse_from is None else seed + 7919 * (t + 1),
              progress=progress)
    what = f"scene {scene.name!r} frame {t}"
    reuse = _reuse_of(scene, t, width, height, reuse_from, se_bound_lsb, held_out,
                      min_passes * spp_per_pass + replicates * max((max_spp - min_passes * spp_per_pass) // replicates, 1)) \
        if reuse_from is not None else None
    while True:
        ref = converge(tracer, width, height, what, reuse=reuse, **kw)
        if reuse is None:
            return ref
        # The kept pixels met the bound under frame t - 1's display transform; this frame's (from
        # its own mean image) may be steeper at their values. Held out, a pixel's reported SE is
        # its value's own samples' spread: choosing pixels by it (or by their value) would select
        # on the value, so where the slope grew past _DRIFT anywhere the frame is rendered whole;
        # otherwise the pixels over the bound are rendered afresh.
        if held_out:
            if np.any(reuse["slope"] > 1 + _DRIFT):
                reuse = None
                continue
            return ref
        over = (E.fold(np.maximum, ref.display_stderr).ravel() > se_bound_lsb * LSB * (1 + _DRIFT)) & reuse["mask"]
        if not over.any():
            return ref
        reuse["mask"] = reuse["mask"] & ~over


def _reuse_of(scene: ResolvedScene, t: int, width: int, height: int, prev: Reference, se_bound_lsb: float,
              held_out: bool, cap_spp: int) -> dict | None:
    """converge's `reuse` from frame t - 1's reference: the pixels references.reuse keeps whose
    estimate met the bound by its own decisions (under the cap; display SE within the bound)."""
    if prev.image.shape != (height, width, 3) or prev.sample_lo is None or prev.half_delta is None:
        raise ReferenceError(f"scene {scene.name!r} frame {t}: the previous frame's reference has another "
                             f"size or keeps no sample extremes or halves; it cannot be reused")
    if bool(prev.held_out) != bool(held_out) or abs(prev.bound_lsb - se_bound_lsb) > 1e-9 * se_bound_lsb:
        raise ReferenceError(f"scene {scene.name!r} frame {t}: the previous frame's reference was rendered "
                             f"with other settings (bound {prev.bound_lsb}, held_out {prev.held_out})")
    mask = reuse_mask(scene, t, width, height)
    if mask is None:
        return None
    # the cap: a pixel that stopped there missed the bound; one under it met it by its deciding
    # samples, so (held out) keeping it selects nothing on the value it reports
    met = prev.spp_map < cap_spp
    if not held_out:
        met &= prev.se_lsb <= se_bound_lsb * (1 + 1e-5)
    mask = (mask & met).ravel()
    if not mask.any():
        return None
    flat = lambda a: np.asarray(a).reshape(width * height, *np.asarray(a).shape[2:])  # noqa: E731
    return {"mask": mask, "image": flat(prev.image).astype(np.float64), "stderr": flat(prev.stderr),
            "dse": flat(prev.display_stderr).astype(np.float64), "floor": flat(prev.display_floor).astype(np.float64),
            "half": flat(prev.half_delta).astype(np.float64), "spp": flat(prev.spp_map).astype(np.int64),
            "lo": flat(prev.sample_lo).astype(np.float64), "hi": flat(prev.sample_hi).astype(np.float64),
            "disp": DisplayTransform.from_reference(prev.image)}


def _deciding_runs(sets: int, deciding: int) -> tuple[int, int]:
    """(runs, deciding runs): `sets` sets of which the first `deciding` decide, in runs of equal
    length that do not straddle the two (one run per set where none such divides both)."""
    size = math.gcd(sets, deciding)
    return sets // size, deciding // size


def converge(tracer, width: int, height: int, what: str, *, se_bound_lsb: float, target_noise_db: float,
             spp_per_pass: int, min_passes: int, replicates: int, max_spp: int, seed: int, held_out: bool,
             progress=None, reuse: dict | None = None) -> Reference:
    """The adaptive loop over any tracer whose `chunked(pix, r, a, rng, groups)` yields (pixels,
    their r set sums (n, r, 3), the smallest and largest sample of each of `groups` runs of
    consecutive sets (n, groups, 3) each). `reuse`: pixels (`mask`, (npix,) bool) whose estimate is
    given, not traced: their `image`, `stderr`, `dse` and `floor` (display SE and its floor under the
    transform `disp`), `half`, `spp`, `lo` and `hi` ((npix, ...) each, see render_reference)."""
    npix, r = width * height, replicates
    start = time.perf_counter()
    history = []
    kept = np.zeros(npix, bool) if reuse is None else np.asarray(reuse["mask"], bool)
    active = ~kept
    kix = np.flatnonzero(kept)                # as indices: a boolean mask is read whole each time
    kept_dse = reuse["dse"][kix] if len(kix) else None

    def record(dse):
        db = E.noise_db(dse)
        spp = float((est.spp * active).mean())
        history.append((spp, time.perf_counter() - start, db, float(dse.max() / LSB)))
        if progress:
            progress(int(round(spp)), db)

    # Pilot: min_passes independent sets (nets) of spp_per_pass at every pixel, which also
    # give each pixel's smallest and largest sample (the unseen-feature floor below).
    pilot = np.empty((npix, min_passes, 3), np.float32)
    lo, hi = np.empty((npix, 3)), np.empty((npix, 3))          # the deciding samples' extremes
    lo_all, hi_all = np.empty((npix, 3)), np.empty((npix, 3))  # every sample's (the reported floor)
    # the deciding sets lead (references.estimates): the extremes come in runs of them
    pg, dg = _deciding_runs(min_passes, min_passes // 2 if held_out else min_passes)
    if kept.any():
        # a given pixel enters as passes that agree (no spread, never refined); its neighbours'
        # floors read its own samples' extremes
        pilot[kept] = reuse["image"][kept][:, None, :]
        lo[kept] = lo_all[kept] = reuse["lo"][kept]
        hi[kept] = hi_all[kept] = reuse["hi"][kept]
    for g, sums, glo, ghi in tracer.chunked(np.flatnonzero(active), min_passes, spp_per_pass,
                                            np.random.default_rng([seed, 8]), pg):
        if not np.all(np.isfinite(sums)):
            raise ReferenceError(f"{what}: the pilot produced NaN/Inf")
        pilot[g] = sums / spp_per_pass
        lo[g], hi[g] = E.fold(np.minimum, glo[:, :dg], 1), E.fold(np.maximum, ghi[:, :dg], 1)
        lo_all[g], hi_all[g] = E.fold(np.minimum, glo, 1), E.fold(np.maximum, ghi, 1)
    est = E.Estimates(pilot, spp_per_pass, r, held_out)
    del pilot
    # the current mean's transform, re-derived every round: one pass of a few samples can be far
    # off (thin bright lines on black: 4.4x the exposure), and the bound must hold in the study's
    disp = DisplayTransform.from_reference(est.dmean.reshape(height, width, 3))
    dse_s = np.zeros((npix, 3))           # from the spread of the samples
    dse_s[est.varies] = E.display_se(disp, est.dmean[est.varies], est.dcov[est.varies])
    floor_d = np.zeros((npix, 3))

    def update_floor(where: np.ndarray):
        wlo = E.window(lo.reshape(height, width, 3), np.minimum).reshape(npix, 3)[where]
        whi = E.window(hi.reshape(height, width, 3), np.maximum).reshape(npix, 3)[where]
        floor_d[where] = E.unseen_floor(disp, est.dmean[where], wlo, whi, est.spp_estimate[where])[0]

    def contrast(lo, hi) -> np.ndarray:    # pixels whose 3x3 window holds more than one value
        return np.flatnonzero(np.any(E.window(hi.reshape(height, width, 3), np.maximum) >
                                     E.window(lo.reshape(height, width, 3), np.minimum), axis=-1).ravel())

    def pin():
        # the given pixels' display SE is their own, their floor in it
        if len(kix):
            dse_s[kix], floor_d[kix] = kept_dse, 0.0

    update_floor(contrast(lo, hi))
    pin()
    dse = np.maximum(dse_s, floor_d)
    record(dse)

    cap = max((max_spp - est.mp) // r, 1)         # samples per replicate
    bound = se_bound_lsb * LSB
    target_mse = 10 ** (-target_noise_db / 10)
    rounds = tightened = 0
    while True:
        worst_s, worst_f = E.fold(np.maximum, dse_s), E.fold(np.maximum, floor_d)
        worst = np.maximum(worst_s, worst_f)
        over = (worst > bound) & (est.m < cap) & active
        spp = est.spp_estimate
        need = E.samples_needed(spp, worst_s, worst_f, bound) * _MARGIN
        want = (np.ceil(need) - spp) / est.re      # per replicate
        if rounds == 0:
            # A pilot spread of min_passes estimates is a rough noise estimate: every pixel
            # whose samples vary gets one set of replicates (R - 1 degrees of freedom).
            over[est.varies] = True
        if not over.any():
            mse = float(np.mean(dse ** 2))
            improvable = np.any((worst > 0) & (est.m < cap) & active)
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
        rg, rdg = _deciding_runs(r, est.rd)
        for a in np.unique(add):          # one set size per group of pixels
            for g, sums, glo, ghi in tracer.chunked(pix[add == a], r, int(a), rng, rg):
                if not np.all(np.isfinite(sums)):
                    raise ReferenceError(f"{what}: round {rounds} produced NaN/Inf")
                est.add(g, int(a), sums)
                lo[g] = np.minimum(lo[g], E.fold(np.minimum, glo[:, :rdg], 1))
                hi[g] = np.maximum(hi[g], E.fold(np.maximum, ghi[:, :rdg], 1))
                lo_all[g] = np.minimum(lo_all[g], E.fold(np.minimum, glo, 1))
                hi_all[g] = np.maximum(hi_all[g], E.fold(np.maximum, ghi, 1))
        dse_s[pix] = E.display_se(disp, est.dmean[pix], est.dcov[pix])
        # the floor moves where a pixel or a neighbour got samples (new extremes, or more samples)
        touched = np.zeros(npix, bool)
        touched[pix] = True
        update_floor(np.flatnonzero(E.dilate(touched.reshape(height, width)).ravel()))
        pin()
        now = DisplayTransform.from_reference(est.dmean.reshape(height, width, 3))
        if now != disp:                   # (to 3 digits) every pixel's display error moves with it
            disp = now
            noisy = np.flatnonzero(E.fold(np.logical_or, np.diagonal(est.dcov, axis1=1, axis2=2) > 0))
            dse_s[:] = 0.0
            dse_s[noisy] = E.display_se(disp, est.dmean[noisy], est.dcov[noisy])
            update_floor(contrast(lo, hi))
        pin()
        dse = np.maximum(dse_s, floor_d)
        rounds += 1
        record(dse)

    # What is reported is the estimate's own: its spread, and the floor from every sample's extremes
    mean, cov = est.estimate()
    disp = DisplayTransform.from_reference(mean.reshape(height, width, 3))
    dse = np.zeros((npix, 3))
    noisy = np.flatnonzero(E.fold(np.logical_or, np.diagonal(cov, axis1=1, axis2=2) > 0))
    dse[noisy] = E.display_se(disp, mean[noisy], cov[noisy])
    spread = dse.copy()
    floor_d, floor_l = np.zeros((npix, 3)), np.zeros((npix, 3))
    where = contrast(lo_all, hi_all)
    wlo = E.window(lo_all.reshape(height, width, 3), np.minimum).reshape(npix, 3)[where]
    whi = E.window(hi_all.reshape(height, width, 3), np.maximum).reshape(npix, 3)[where]
    floor_d[where], floor_l[where] = E.unseen_floor(disp, mean[where], wlo, whi, est.spp_estimate[where])
    dse = np.maximum(dse, floor_d)
    lin_se = np.maximum(E.linear_se(cov), floor_l)
    spp_all = est.spp.copy()
    half = est.half_delta(mean)
    if len(kix):
        k = kix
        mean[k], lin_se[k], half[k], spp_all[k] = reuse["image"][k], reuse["stderr"][k], reuse["half"][k], reuse["spp"][k]
        # the display SE of a given pixel under this frame's transform: its own, times how much
        # the transform's slope at its value moved (not at all under the same transform: x / x is 1)
        ratio = np.ones((len(k), 3))
        if disp != reuse["disp"]:
            diag = np.zeros((len(k), 3, 3))
            diag[:, [0, 1, 2], [0, 1, 2]] = reuse["stderr"][k].astype(np.float64) ** 2
            was = E.display_se(reuse["disp"], mean[k], diag)
            now_ = E.display_se(disp, mean[k], diag)
            ratio = np.divide(now_, was, out=ratio, where=was > 0)
        dse[k], floor_d[k] = reuse["dse"][k] * ratio, reuse["floor"][k] * ratio
        reuse["slope"] = np.ones(npix)
        reuse["slope"][k] = E.fold(np.maximum, ratio)
        spread[k] = dse[k]
    spp_map = spp_all.reshape(height, width)
    b0 = se_bound_lsb * LSB
    missed = (E.fold(np.maximum, dse) > b0 * (1 + 1e-5)) & active
    needed = (E.samples_needed(est.spp_estimate, E.fold(np.maximum, spread), E.fold(np.maximum, floor_d), b0)[missed]
              * (est.spp[missed] / est.spp_estimate[missed]))
    return Reference(mean.reshape(height, width, 3).astype(np.float32),
                     lin_se.reshape(height, width, 3).astype(np.float32),
                     int(round(spp_map.mean())), min_passes, time.perf_counter() - start, E.noise_db(dse),
                     spp_map=spp_map.astype(np.int32), display_stderr=dse.reshape(height, width, 3).astype(np.float32),
                     bound_lsb=float(se_bound_lsb), rounds=rounds, _history=history,
                     display_floor=floor_d.reshape(height, width, 3).astype(np.float32),
                     half_delta=half.reshape(height, width, 3).astype(np.float32),
                     spp_needed=int(np.ceil(needed.max())) if len(needed) else 0, held_out=held_out,
                     sample_lo=lo_all.reshape(height, width, 3).astype(np.float32),
                     sample_hi=hi_all.reshape(height, width, 3).astype(np.float32),
                     reused=kept.reshape(height, width).copy() if reuse is not None else None)
