"""An FSR 2-class temporal upscaler, pass by pass as AMD's FidelityFX Super Resolution 2 runs them
(taa_impl.fsr2_passes holds the passes; this module the history and the accumulate pass).

Per frame, at the render resolution: 1 auto exposure (the luminance pyramid's average log luma);
2 reconstruct and dilate (closest-depth 3x3 depth and motion, the previous depth reconstructed by
scattering); 3 depth clip (disocclusion); 4 create locks (thin features). At the output resolution,
5-6 reproject and accumulate, per output pixel:
 - the dilated motion at the render pixel the output centre lies in, in output pixels;
 - the history (colour, accumulated weight, lock lifetime and trust luma, three lumas) reprojected:
   colour with Lanczos-2 (deringed), the rest from the nearest texel; none off-screen;
 - the current frame upsampled (Lanczos-2 over the render samples' jittered positions, kernel
   widened for new and disoccluded samples) with its YCoCg rectification box;
 - locks: a new lock where a thin feature's sample landed; a lock lives `lock_lifetime` frames
   unless the depth clip or a change of luma (> `lock_luma_tolerance` of its trust luma) kills it;
 - the base accumulation: the history's weight, times (1 - depth clip), at most 10 upsample
   weights when moving, at most `max_accumulation` (more where locked);
 - rectification: the history clamped into (box centre +/- box_scale std) intersected with the
   samples' min/max; a locked or luma-unstable pixel keeps its history in proportion, and a
   clamped pixel's weight drops to 0.1 in the same proportion;
 - accumulate in the reversible tone map c / (max(r,g,b) + 1): lerp(history, upsampled,
   w_up / (weight + w_up)), mapped back;
7 RCAS on the output (tone-mapped, sharpness in FSR 2's [0, 1], 2 - 2 sharpness stops); the history
keeps the unsharpened result.
Departures from FSR 2 (checked against FSR 2.2.1's shaders, commit 1680d1e), each for a reason:
 - the history's weight: 2.2.1 stores none (base accumulation 1, upsample weight = sum of Lanczos
   weights / 12, i.e. a fixed exponential history: `history='fixed'`); by default it is accumulated
   and capped at `max_accumulation` (as FSR 2.1 stored it), so a static pixel converges like the
   study's TAAs;
 - RCAS runs on the tone-mapped output (2.2.1: on exposed linear values, with its noise term):
   RCAS's limits assume [0, 1]; its limiters take the centre pixel in (min(ring, centre),
   max(ring, centre)), as FSR 1.0's RCAS does: FSR 2's copy uses the ring alone, which at a local
   peak overshoots 1 (0.99 on 0.5: 2.46), past what the inverse tone map can undo;
 - the upsample (FSR 2's: the 3x3 samples around floor(output centre), weights zeroed at or
   below FSR2_EPSILON, the colour deringed into the samples' min/max): off-screen samples stay out
   of the rectification box and its min/max (FSR 2 loads them unclamped, its ClampLoad given a
   zero offset: out-of-range loads, black in Direct3D 12, which darken the box at the border;
   tests/test_fsr2_oracle.py holds both forms);
 - locks: lifetime in frames and a trust luma (2.2.1: lifetime drained by the upsample weight and a
   1/32-resolution shading-change luma);
 - the luma instability test (fsr2_passes.luma_instability), and no reactive, transparency or
   motion-divergence masks (the study's scenes give none);
 - the exact Lanczos-2 (2.2.1 uses its polynomial approximation);
 - RECTIFY_TOLERANCE (below).
"""
from __future__ import annotations

from dataclasses import dataclass

import backend  # noqa: F401
from backend import dr, mi

from . import fsr2_passes as P
from . import kernels as K
from .base import Inputs
from .upscale import Upscaler, check_scale, fsr2_phase_count, lanczos2_sample


# A history within two 8-bit steps (exposed units) of the box is not rectified. Departure from FSR 2:
# without it float noise on flat regions (a box of near-zero size) clamps the history every frame and
# its weight drops to 0.1 (measured: 91 % of pipe's pixels at scale 1, 160x90; 39.1 against 41.2 dB).
RECTIFY_TOLERANCE = 2.0 / 255.0


HISTORY_MODELS = ("accumulated", "fixed")


@dataclass(frozen=True)
class FSR2Params:
    render_scale: float = 0.5
    enable_sharpening: bool = True    # RCAS, as FSR 2's sample ships it
    sharpness: float = 0.8            # FSR 2's [0, 1]; RCAS at 2 - 2 sharpness stops
    auto_exposure: bool = True
    depth_clip: bool = True
    locks: bool = True
    lock_lifetime: int = 32           # frames a lock lasts unless killed
    lock_luma_tolerance: float = 0.5  # relative change of luma that kills a lock
    luma_instability: bool = True
    max_accumulation: float = 32.0    # the history's weight cap, in Lanczos weights (~frames at scale 1)
    history: str = "accumulated"      # or 'fixed': FSR 2.2.1's (no stored weight: base 1, upsample weight / 12)

    def __post_init__(self):
        object.__setattr__(self, "render_scale", check_scale(self.render_scale))
        if not (0.0 <= float(self.sharpness) <= 1.0):
            raise ValueError(f"sharpness must be in [0, 1], got {self.sharpness!r}")
        if int(self.lock_lifetime) < 1:
            raise ValueError(f"lock_lifetime must be >= 1 frame, got {self.lock_lifetime!r}")
        if not (0 < float(self.lock_luma_tolerance) < 10):
            raise ValueError(f"lock_luma_tolerance must be in (0, 10), got {self.lock_luma_tolerance!r}")
        if not (1.0 <= float(self.max_accumulation) <= 1e4):
            raise ValueError(f"max_accumulation must be in [1, 1e4], got {self.max_accumulation!r}")
        if self.history not in HISTORY_MODELS:
            raise ValueError(f"history must be one of {HISTORY_MODELS}, got {self.history!r}")
        for flag in ("enable_sharpening", "auto_exposure", "depth_clip", "locks", "luma_instability"):
            object.__setattr__(self, flag, bool(getattr(self, flag)))


class FSR2(Upscaler):
    name = "fsr2"
    Params = FSR2Params
    # cameras: the depth clip's Kfov, from the camera's field of view
    contract = Inputs(buffers={"color", "depth", "motion"}, sampling="sequence", upsamples=True, cameras=True)

    @classmethod
    def jitter_period(cls, params) -> int:
        """FSR 2's phase count, int(8 ratio^2), of the ratio 1 / render_scale (8, 17, 13, 32 at
        scales 1, 0.67, 0.77, 0.5)."""
        return fsr2_phase_count(1.0, 1.0 / params.render_scale)

    def _clear_state(self) -> None:
        self._history = None      # linear RGB (not exposed), the unsharpened output
        self._weight = None       # accumulated upsample weight
        self._lock = None         # lock lifetime remaining in [0, 1]
        self._trust = None        # the luma a lock was made on
        self._lumas = None        # the three previous tone-mapped lumas, newest first

    def _upscale(self, b, fr, frame, jitter):
        p = self.params
        far = frame.far
        o = fr.output
        c = b["color"]
        # 1. exposure
        exposure = P.auto_exposure(c) if p.auto_exposure else mi.Float(1.0)
        # 2. reconstruct and dilate; 3. depth clip (at the render resolution)
        dil_depth, dil_motion, prev_depth = P.reconstruct_and_dilate(fr, b["depth"], b["motion"], far)
        fresh = self._history is None
        if p.depth_clip and not fresh:
            tan_half = tuple(float(v) for v in frame.cameras[0].tan_half)
            clip_r = P.depth_clip(fr, dil_depth, dil_motion, prev_depth, tan_half)
        else:
            clip_r = dr.zeros(mi.Float, fr.render.n)
        near = fr.nearest()
        vr = dr.gather(mi.Vector2f, dil_motion, near)
        velocity = mi.Vector2f(vr.x * fr.rx, vr.y * fr.ry)
        hr_vel = dr.norm(velocity)
        clip = dr.gather(mi.Float, clip_r, near)
        # 5. reproject the history
        px, py, valid = K.previous_position(o, velocity)
        if fresh:
            valid = dr.full(mi.Bool, False, o.n)
        new_sample = ~valid
        # 6. upsample the current frame
        ratio = 1.0 / fr.sx
        bias_max = min(1.99, ratio)
        bias_min = max(1.0, (1.0 + bias_max) * 0.3)
        # per-size constants as opaque kernel parameters (a literal would compile per size)
        bias = K.opaque_float(bias_max) + K.opaque_float(bias_min - bias_max) * dr.maximum(
            0.25 * clip, dr.select(new_sample, 1.0, 0.0))
        curve = -2.0 - K.clamp01(hr_vel / 50.0)
        cur = K.rgb_to_ycocg(c * exposure)
        up, w_up, centre, vec, amin, amax = P.upsample(fr, cur, jitter, bias, curve)
        fixed = p.history == "fixed"
        if fixed:                 # FSR 2.2.1: the sample's weight is a twelfth of its Lanczos weights
            w_up = w_up * (1.0 / 12.0)
        up_rgb = dr.maximum(K.ycocg_to_rgb(up), 0.0)
        luma_t = K.luminance(P.tonemap(dr.maximum(K.ycocg_to_rgb(centre), 0.0)), P.LUMA)
        if fresh:
            h_rgb = up_rgb
            weight = dr.zeros(mi.Float, o.n)
            lock, trust = dr.zeros(mi.Float, o.n), dr.zeros(mi.Float, o.n)
            lumas = [luma_t, luma_t, luma_t]
        else:
            h_rgb = dr.maximum(lanczos2_sample(o, self._history, px, py) * exposure, 0.0)
            ni = K.nearest_index(o, px, py)
            weight = dr.select(valid, 1.0 if fixed else dr.gather(mi.Float, self._weight, ni), 0.0)
            lock = dr.select(valid, dr.gather(mi.Float, self._lock, ni), 0.0)
            trust = dr.gather(mi.Float, self._trust, ni)
            lumas = [dr.select(valid, dr.gather(mi.Float, lh, ni), luma_t) for lh in self._lumas]
        # 4. locks: new ones where a thin feature's sample landed, then kill and age
        if p.locks:
            lock_luma = K.luminance(P.tonemap(c * exposure), P.LUMA)
            newl = P.create_locks(fr, P.thin_feature(fr, lock_luma), jitter)
            changed = dr.abs(luma_t - trust) > p.lock_luma_tolerance * dr.maximum(trust, P.EPS)
            lock = dr.select(changed | (clip > 0.1), 0.0, dr.maximum(lock - 1.0 / p.lock_lifetime, 0.0))
            trust = dr.select(newl & (lock <= 0.0), luma_t, trust)
            lock = dr.select(newl, 1.0, lock)
            lock_c = K.clamp01(lock)
        else:
            lock_c = dr.zeros(mi.Float, o.n)
        unstable = (P.luma_instability(luma_t, lumas, vec.x, new_sample) * (1.0 - K.clamp01(dr.power(hr_vel, 1 / 6)))
                    if p.luma_instability and not fresh else dr.zeros(mi.Float, o.n))
        # base accumulation
        weight = weight * (1.0 - clip)
        moving = K.clamp01(hr_vel * 10.0)
        weight = dr.minimum(weight, weight + (w_up * 10.0 - weight) * moving)
        if not fixed:
            weight = dr.minimum(weight, p.max_accumulation * (1.0 + lock_c))
        # rectify the history
        influence = min(20.0, (1.0 / (fr.sx * fr.sy)) ** 3)
        box_scale = K.opaque_float(influence) + K.opaque_float(1.0 - influence) * dr.maximum(
            clip, K.clamp01(hr_vel / 20.0))
        bmin = dr.maximum(amin, centre - vec * box_scale)
        bmax = dr.minimum(amax, centre + vec * box_scale)
        h = K.rgb_to_ycocg(h_rgb)
        tol = RECTIFY_TOLERANCE
        outside = dr.any((h < bmin - tol) | (h > bmax + tol)) & ~new_sample
        keep = K.clamp01(dr.maximum(unstable, lock_c))
        h = dr.select(outside, K.lerp(dr.clip(h, bmin, bmax), h, keep), h)
        weight = dr.select(outside, K.lerp(dr.minimum(weight, 0.1), weight, keep), weight)
        h_rgb = dr.maximum(K.ycocg_to_rgb(h), 0.0)
        # accumulate in the reversible tone map
        total = dr.maximum(weight + w_up, P.EPS)
        alpha = dr.select(new_sample, 1.0, w_up / total)
        out_t = K.lerp(P.tonemap(h_rgb), P.tonemap(up_rgb), alpha)
        out = P.inverse_tonemap(out_t)
        dr.eval(out, total, lock, trust)
        self._history = out / exposure
        self._weight = dr.minimum(total, p.max_accumulation * 2.0)
        self._lock, self._trust = lock, trust
        self._lumas = [luma_t, lumas[0], lumas[1]]
        self._terms = {"velocity": velocity, "depth_clip": clip, "upsample_weight": w_up, "accumulation": total,
                       "lock": lock_c, "luma_instability": unstable, "alpha": alpha,
                       "history_valid": mi.Float(dr.select(valid, 1.0, 0.0))}
        # 7. RCAS on the tone-mapped output
        if p.enable_sharpening:
            out = P.inverse_tonemap(P.rcas(o, out_t, 2.0 - 2.0 * p.sharpness))
        return dr.maximum(out, 0.0) / exposure
