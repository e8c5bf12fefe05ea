"""The passes of the FSR 2-class upscaler (taa_impl.fsr2), each a function of Dr.Jit arrays, named
as AMD's FidelityFX Super Resolution 2 names them. Written from FSR 2's documentation and
algorithm (its public repository, MIT), not copied; where this code departs from it, it says so.

Render-resolution images live on `fr.render` (taa_impl.upscale.Frames), output-resolution ones on
`fr.output`; depth is linear view depth (world units, larger = farther; FSR 2 takes device depth
and converts it to this).
"""
from __future__ import annotations

import math

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .upscale import lanczos2

LUMA = (0.2126, 0.7152, 0.0722)
EPS = 1e-6


# -- 1. luminance pyramid: auto exposure --------------------------------------------------------
def auto_exposure(color):
    """FSR 2's exposure from the frame's average log luminance (its luminance pyramid reduces the
    frame to that one value): Lavg = exp(mean log luma); the exposure value at ISO 100,
    EV100 = log2(Lavg S / K) with S = 100, K = 12.5, and q = 0.65 give
    Lmax = 78 / (q S) 2^EV100 = 9.6 Lavg; exposure = 1 / Lmax. A one-entry array (kept on the
    device: as a literal it would make every frame's kernels new)."""
    luma = dr.maximum(K.luminance(color, LUMA), 1e-8)
    log_luma = dr.log(luma)
    # the mean as dr.mean computes it, with 1 / n opaque (a literal 1 / n is a kernel per size)
    lavg = dr.exp(dr.sum(log_luma) * K.opaque_rcp(dr.width(log_luma)))
    s, k, q = 100.0, 12.5, 0.65
    return 1.0 / (78.0 / (q * s) * (lavg * s / k))


# -- reversible tone map ------------------------------------------------------------------------
def tonemap(c):
    """c / (max(r, g, b) + 1): maps [0, inf) into [0, 1), colour ratios kept."""
    return c * dr.rcp(dr.maximum(dr.maximum(c.x, c.y), c.z) + 1.0)


def inverse_tonemap(c):
    """The exact inverse, c / (1 - max(r, g, b)) (max clamped below 1)."""
    return c * dr.rcp(dr.maximum(1.0 - dr.maximum(dr.maximum(c.x, c.y), c.z), 1e-6))


# -- 2. reconstruct and dilate ------------------------------------------------------------------
def reconstruct_and_dilate(fr, depth, motion, far: float):
    """Dilated depth and motion (the closest-depth 3x3 pixel's), and the reconstructed previous
    depth: each pixel's depth scattered with a min onto the 2x2 texels its previous position
    (from the dilated motion) falls between, as FSR 2 reconstructs the previous frame's depth from
    this frame's. Unwritten texels hold `far`."""
    g = fr.render
    best = K.closest_index(g, depth)
    dil_depth = dr.gather(mi.Float, depth, best)
    dil_motion = dr.gather(mi.Vector2f, motion, best)
    px = mi.Float(g.x) + 0.5 - dil_motion.x
    py = mi.Float(g.y) + 0.5 - dil_motion.y
    x0, y0 = mi.Int32(dr.floor(px - 0.5)), mi.Int32(dr.floor(py - 0.5))
    prev = dr.zeros(mi.Float, g.n) + K.opaque_float(far)    # opaque: `far` changes between calls
    for dx in (0, 1):
        for dy in (0, 1):
            xi, yi = x0 + dx, y0 + dy
            on = (xi >= 0) & (xi < g.W) & (yi >= 0) & (yi < g.H)
            dr.scatter_reduce(dr.ReduceOp.Min, prev, depth, yi * g.W + xi, on)
    dr.eval(prev)
    return dil_depth, dil_motion, prev


# -- 3. depth clip ------------------------------------------------------------------------------
KSEP = 1.37e-5                        # FSR 2's depth separation constant
RECONSTRUCTED_DEPTH_WEIGHT_MIN = 0.01  # bilinear taps below this weight are not read


def depth_clip(fr, dil_depth, dil_motion, prev_depth, tan_half: tuple[float, float]):
    """Disocclusion in [0, 1] per render pixel: the reconstructed previous depth read at the
    pixel's previous position (its 4 bilinear taps); where the surface now is farther than what
    was there by more than the separation FSR 2 requires, Ksep Kfov |render size| max(depths), the
    pixel was hidden last frame. clip = 1 - mean over those taps of saturate(separation / diff)^p,
    p = lerp(1, 3, |render size| / |1920 x 1080|) saturated; 0 where no tap is farther. (FSR 2.2.1
    also multiplies by a vertical depth-slope test of the previous depth, EvaluateSurface; not here.)"""
    g = fr.render
    px = mi.Float(g.x) + 0.5 - dil_motion.x
    py = mi.Float(g.y) + 0.5 - dil_motion.y
    x0, y0, tx, ty = K._texel_coords(g, px, py)
    kfov = math.sqrt(tan_half[0] ** 2 + tan_half[1] ** 2 + 1.0)   # |corner| / |centre| at one depth
    size = math.hypot(g.w, g.h)
    power = 1.0 + 2.0 * min(1.0, size / math.hypot(1920, 1080))
    # per-size and per-camera constants as kernel parameters; an integer power stays a literal
    # (Dr.Jit expands it into products, which an opaque exponent would not give)
    sep_scale = K.opaque_float(KSEP * kfov * size)
    if power != int(power):
        power = K.opaque_float(power)
    acc = dr.zeros(mi.Float, g.n)
    wsum = dr.zeros(mi.Float, g.n)
    for dx, dy, w in ((0, 0, (1 - tx) * (1 - ty)), (1, 0, tx * (1 - ty)), (0, 1, (1 - tx) * ty), (1, 1, tx * ty)):
        xi, yi = x0 + dx, y0 + dy
        on = (xi >= 0) & (xi < g.W) & (yi >= 0) & (yi < g.H) & (w > RECONSTRUCTED_DEPTH_WEIGHT_MIN)
        prev = dr.gather(mi.Float, prev_depth, dr.clip(yi, 0, g.H - 1) * g.W + dr.clip(xi, 0, g.W - 1))
        diff = dil_depth - prev
        use = on & (diff > 0)
        sep = sep_scale * dr.maximum(dil_depth, prev)
        acc += dr.select(use, dr.power(K.clamp01(sep / dr.maximum(diff, 1e-30)), power) * w, 0.0)
        wsum += dr.select(use, w, 0.0)
    return dr.select(wsum > 0, K.clamp01(1.0 - acc / dr.maximum(wsum, 1e-30)), 0.0)


# -- 4. create locks ----------------------------------------------------------------------------
SIMILAR_THRESHOLD = 1.05      # two lumas within 5 % are "similar"
# the 3x3 (row-major, 4 = centre) quads that make a pixel part of a 2x2 block, not a thin feature
QUADS = ((0, 1, 3, 4), (1, 2, 4, 5), (3, 4, 6, 7), (4, 5, 7, 8))


def thin_feature(fr, luma):
    """FSR 2's thin-feature test per render pixel (1 = lock it): the centre's luma is a ridge (above
    or below every dissimilar neighbour) and no 2x2 quad through the centre is all similar to it."""
    g = fr.render
    lum = dr.maximum(luma, EPS)
    similar, lo, hi = [], dr.full(mi.Float, 3.4e38, g.n), dr.zeros(mi.Float, g.n)
    for o in K.OFFSETS_3X3:
        if o == (0, 0):
            similar.append(dr.full(mi.Bool, True, g.n))
            continue
        s = g.tap(lum, *o)
        sim = dr.maximum(s, lum) / dr.minimum(s, lum) < SIMILAR_THRESHOLD
        similar.append(sim)
        lo = dr.select(sim, lo, dr.minimum(lo, s))
        hi = dr.select(sim, hi, dr.maximum(hi, s))
    ridge = (lum > hi) | (lum < lo)
    in_quad = dr.full(mi.Bool, False, g.n)
    for q in QUADS:
        in_quad |= similar[q[0]] & similar[q[1]] & similar[q[2]] & similar[q[3]]
    return ridge & ~in_quad


def create_locks(fr, thin, jitter):
    """New locks at output resolution: each thin render pixel locks the output pixel its jittered
    sample lies in (FSR 2 writes the lock where the sample lands)."""
    g, o = fr.render, fr.output
    sx = (mi.Float(g.x) + 0.5 + jitter[0]) * fr.rx
    sy = (mi.Float(g.y) + 0.5 + jitter[1]) * fr.ry
    idx = K.nearest_index(o, sx, sy)
    new = dr.zeros(mi.Float, o.n)
    dr.scatter(new, 1.0, idx, thin)
    dr.eval(new)
    return new > 0.5


# -- 6. upsample --------------------------------------------------------------------------------
FSR2_EPSILON = 1e-3   # FSR 2's: weights at or below it count as none


def upsample(fr, color_ycocg, jitter, kernel_bias, curve_bias):
    """FSR 2's upsample of the current frame at output resolution. Per output pixel, its centre u
    in render pixels and the nine render samples in floor(u) + {-1, 0, 1}^2, offset d = sample's
    jittered position - u: the colour sum of Lanczos-2(|d| `kernel_bias`) c over the on-screen
    ones (`kernel_bias`: render pixels times the downsample ratio, i.e. output pixels, so the
    kernel spans the same output footprint at every scale), normalised and deringed into the
    samples' min/max where the weight sum exceeds FSR2_EPSILON (else weight 0 and the sum as it
    is); the rectification box: moments with weights exp(`curve_bias` |d|^2) and the min/max.
    Departure: off-screen samples stay out of the box (FSR 2 reads them unclamped, an
    out-of-range load: black in Direct3D 12). Returns (colour, weight = sum of Lanczos weights,
    box centre, box vec (std), aabb min, aabb max)."""
    g, n = fr.render, fr.output.n
    ix, iy = mi.Int32(dr.floor(fr.ux)), mi.Int32(dr.floor(fr.uy))
    acc, wsum = dr.zeros(mi.Color3f, n), dr.zeros(mi.Float, n)
    m1, m2, bw = dr.zeros(mi.Color3f, n), dr.zeros(mi.Color3f, n), dr.zeros(mi.Float, n)
    amin, amax = dr.full(mi.Color3f, 3.4e38, n), dr.full(mi.Color3f, -3.4e38, n)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            xi, yi = ix + dx, iy + dy
            on = (xi >= 0) & (xi < g.W) & (yi >= 0) & (yi < g.H)
            c = dr.gather(mi.Color3f, color_ycocg, dr.clip(yi, 0, g.H - 1) * g.W + dr.clip(xi, 0, g.W - 1))
            ox = mi.Float(xi) + 0.5 + jitter[0] - fr.ux
            oy = mi.Float(yi) + 0.5 + jitter[1] - fr.uy
            d2 = ox * ox + oy * oy
            w = dr.select(on, lanczos2(dr.sqrt(d2) * kernel_bias), 0.0)
            acc += c * w
            wsum += w
            bwi = dr.select(on, dr.exp(curve_bias * d2), 0.0)
            m1 += c * bwi
            m2 += c * c * bwi
            bw += bwi
            amin = dr.select(on, dr.minimum(amin, c), amin)
            amax = dr.select(on, dr.maximum(amax, c), amax)
    ok = wsum > FSR2_EPSILON
    col = dr.select(ok, dr.clip(acc / dr.select(ok, wsum, 1.0), amin, amax), acc)
    bw = dr.select(dr.abs(bw) > FSR2_EPSILON, bw, 1.0)
    centre = m1 / bw
    vec = dr.sqrt(dr.abs(m2 / bw - centre * centre))
    return col, dr.select(ok, wsum, 0.0), centre, vec, amin, amax


# -- 6b. luma instability -----------------------------------------------------------------------
UNORM = 1.0 / 255.0


def luma_instability(luma, hist, box_luma_vec, fresh):
    """1 where the pixel's luma has flipped direction on each of the last three frames by at least
    one 8-bit step (a flicker the history should absorb rather than follow), weighted by
    saturate(box size / 0.1)^6 as FSR 2 does (a flat neighbourhood has nothing to flicker between).
    `hist`: the three previous lumas (newest first); `fresh`: no usable history. Departure: FSR 2
    compares the current change with earlier same-sign changes over four frames; this is the
    plain alternation test."""
    d0 = luma - hist[0]
    d1 = hist[0] - hist[1]
    d2 = hist[1] - hist[2]
    flip = (d0 * d1 < 0) & (d1 * d2 < 0) & (dr.abs(d0) >= UNORM)
    size = dr.power(K.clamp01(box_luma_vec / 0.1), 6.0)
    return dr.select(flip & ~fresh, size, 0.0)


# -- 7. RCAS ------------------------------------------------------------------------------------
RCAS_LIMIT = 0.25 - 1.0 / 16.0


def rcas(grid, c, sharpness_stops: float):
    """Robust contrast-adaptive sharpening on [0, 1] colours (the tone-mapped output): the cross
    neighbours' lobe, limited so the result cannot leave the neighbourhood's range.
    hitMin = min(mn4, e) / (4 mx4), hitMax = (1 - max(mx4, e)) / (4 mn4 - 4), lobe =
    max(-RCAS_LIMIT, min(max_rgb(max(-hitMin, hitMax)), 0)) 2^-stops,
    out = (lobe (b + d + f + h) + e) / (4 lobe + 1)."""
    b, d = grid.tap(c, 0, -1), grid.tap(c, -1, 0)
    f, h = grid.tap(c, 1, 0), grid.tap(c, 0, 1)
    mn4 = dr.minimum(dr.minimum(b, d), dr.minimum(f, h))
    mx4 = dr.maximum(dr.maximum(b, d), dr.maximum(f, h))
    hit_min = dr.minimum(mn4, c) / dr.maximum(4.0 * mx4, 1e-30)
    hit_max = (1.0 - dr.maximum(mx4, c)) / dr.minimum(4.0 * mn4 - 4.0, -1e-30)
    lobe3 = dr.maximum(-hit_min, hit_max)
    lobe = dr.maximum(-RCAS_LIMIT, dr.minimum(dr.maximum(dr.maximum(lobe3.x, lobe3.y), lobe3.z), 0.0))
    lobe = lobe * 2.0 ** -float(sharpness_stops)
    return (b + d + f + h) * lobe / (4.0 * lobe + 1.0) + c / (4.0 * lobe + 1.0)
