"""Converged references: independent passes until the reference's own noise is far below the
errors it will judge.

Each pass is a Mitsuba render (multi-jittered samples, box filter, float32) with its own seed, so
the passes are independent estimates of the pixel-area integral. Their spread gives the per-pixel
standard error of the mean; we measure it on display images (the spec section 8 transform, key
frozen from the first passes) and report it as a PSNR: noise_psnr = 10 log10(1 / mean(SE^2)).
Passes are added until noise_psnr >= target, predicting the count from SE ~ 1/sqrt(passes).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from backend import dr, mi
from display import DisplayTransform
from scenes import ResolvedScene
from shading import frame_geometry, shade, trace_visible

from .mitsuba_scene import SharedShadingIntegrator, path_integrator, path_scene, sensor


class ReferenceError(RuntimeError):
    pass


@dataclass
class Reference:
    image: np.ndarray        # (H, W, 3) float32 linear HDR, mean over all samples
    stderr: np.ndarray       # (H, W, 3) float32 per-pixel standard error of the mean (linear)
    spp: int
    passes: int
    seconds: float
    noise_psnr_db: float     # display-domain noise of the mean, as PSNR
    key: str = ""            # content hash the cache filed it under

    @property
    def noise_history(self):
        return getattr(self, "_history", [])


def _welford(mean, m2, x, n):
    """Running mean and sum of squared deviations after the n-th sample x (in place after the first)."""
    if mean is None:
        return x.copy(), np.zeros_like(x)
    d = x - mean
    mean += d / n
    m2 += d * (x - mean)
    return mean, m2


def _display_noise_db(var_sum: np.ndarray, n: int) -> float:
    mse = float(np.mean(var_sum / max(n - 1, 1) / n))
    return float("inf") if mse == 0 else 10 * math.log10(1.0 / mse)


def render_reference(scene: ResolvedScene, t: int, width: int, height: int, *,
                     target_noise_db: float = 60.0, spp_per_pass: int = 64, min_passes: int = 8,
                     max_spp: int = 1 << 16, progress: Callable[[int, float], None] | None = None
                     ) -> Reference:
    cam = scene.camera(t, width, height)
    path = scene.desc.transport == "path"
    if path and any(a is not None for a in scene.alphas):
        # Mitsuba's path tracer tests shadow rays with ray_test, which sees a masked surface as
        # opaque, and spends a bounce on each cut-out crossed: the reference would be wrong.
        raise ReferenceError(f"scene {scene.name!r}: transport 'path' does not support alpha cut-outs "
                             "(Mitsuba's path tracer treats masked surfaces as opaque to shadow rays); "
                             "use direct_shadows")
    if path:
        mscene, integ = path_scene(scene, t), path_integrator(scene.desc.path_max_depth)
    else:
        geo = frame_geometry(scene, t)
        mscene, integ = geo.mitsuba, SharedShadingIntegrator(geo, cam.position)
    sens = sensor(cam, spp_per_pass, alpha=path)
    background = np.asarray(scene.desc.background, np.float64)
    start = time.perf_counter()
    mean = m2 = None          # Welford in the linear domain (stderr) ...
    dmean = dm2 = None        # ... and in the display domain (noise target)
    disp = None
    n, noise_db, history = 0, 0.0, []
    max_passes = max(min_passes, max_spp // spp_per_pass)
    wanted = min_passes
    while n < wanted:
        img = np.asarray(mi.render(mscene, sensor=sens, integrator=integ, seed=n,
                                   spp=spp_per_pass), np.float64)
        if path:   # rgba: composite the fraction of samples that missed over the background
            img = img[..., :3] + (1.0 - img[..., 3:4]) * background
        if not np.all(np.isfinite(img)):
            raise ReferenceError(f"scene {scene.name!r} frame {t}: pass {n} produced NaN/Inf")
        n += 1
        mean, m2 = _welford(mean, m2, img, n)
        if disp is None:    # the key of one 64-spp pass is the converged key to many digits
            disp = DisplayTransform.from_reference(img)
        dmean, dm2 = _welford(dmean, dm2, disp.encode(img), n)
        if n >= 2:
            noise_db = _display_noise_db(dm2, n)
            history.append((n * spp_per_pass, time.perf_counter() - start, noise_db))
        if progress:
            progress(n * spp_per_pass, noise_db)
        if n >= wanted and n >= min_passes and noise_db < target_noise_db and n < max_passes:
            # SE^2 ~ 1/passes: predict how many passes reach the target, plus 10 % margin.
            need = math.ceil(n * 10 ** ((target_noise_db - noise_db) / 10) * 1.1)
            wanted = min(max(need, n + 1), max_passes)
    se = np.sqrt(m2 / max(n - 1, 1) / n)
    ref = Reference(mean.astype(np.float32), se.astype(np.float32), n * spp_per_pass, n,
                    time.perf_counter() - start, noise_db)
    ref._history = history
    return ref


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
