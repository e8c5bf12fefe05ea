"""Ferrando's simple TAA (Ferrando 2018, U-Tad master's thesis, ch. 5), as variants of the
baseline where Ferrando's text differs from it.

What the seed prints (its §5.1-5.6, GLSL 330 + C++):
- one history buffer (the previous anti-aliased output, §5.1); Halton jitter of the MVP (§5.2);
- motion vectors from the depth buffer and the current and previous view-projection matrices only
  (GPU Gems 3 ch. 27, §5.3): un-project the pixel with inverse(VP) at its depth, re-project with
  PrevVP, velocity = (current NDC - previous NDC) / 2. Camera motion only: moving objects get the
  motion of the static world behind them (a depth-only reprojection is wrong for moving objects --
  this variant exists to measure that);
- the blend is a plain lerp with a fixed weight, no luminance feedback and no dilation of the
  velocity (each pixel uses its own). The text (§5.4) says "a value of 5 %, as some commercial games
  use [Xu 2016]" (5 % of the new frame, i.e. history weight 0.95); the §5.4 shader blends
  mix(current, history(uv + velocity), 0.3f) (history weight 0.3, no clamp) and the §5.5 shader,
  "modified to clamp first", mix(current, clamp(history, minVal, maxVal), 0.60f) (history weight 0.6);
- neighbourhood clamping (§5.5): the text says each pixel is compared with its neighbours "in the
  history buffer", and the shader takes minVal / maxVal over the 9 bilinear taps of the *history*
  texture at uvLast + the 3x3 offsets (offsets hard-coded for 1920x1080; minVal starts at
  (1, 1, 1, 0), maxVal at 0), then clamps the history sample at uvLast into that range;
- an optional sharpen, Xu's [[0,-1,0],[-1,5,-1],[0,-1,0]], clamped to [0, 1] (§5.6); the results
  call it possibly "excessive" and leave it to the user.

What looks like a mistake in the seed, and what this module does about it:
1. The history-neighbourhood clamp is a no-op: the centre tap (offset (0, 0)) of the 9 is the very
   sample being clamped, so min <= h <= max always (the initial values 1 and 0 only widen the range;
   they cannot shrink it below a tap). It cannot stop ghosting. `clamp='history'` implements it as
   printed (its box is in debug_terms as clamp_min / clamp_max, so the no-op is visible and tested);
   `clamp='current'` is the usual form that does what the text wants (min/max of the *current*
   frame's 3x3 around the pixel; clamp, not clip); `clamp='none'` is the §5.4 shader.
2. Three blend weights for one technique: 5 % (text) against 0.3 and 0.6 (code). In GLSL mix(x, y, a)
   weights y by a, so the code keeps only 30 % / 60 % history -- an exponential window of about
   (1 + k) / (1 - k) = 1.9 / 4 frames, far too short to average a 16-sample jitter sequence, against
   about 39 frames for the text's 0.95. The presets keep each reading apart (below).
3. Sign of the motion vector: the text stores CP (previous - current), the shader computes
   current - previous and then samples the history at uv + velocity, i.e. at current + (current -
   previous): the wrong way for any camera motion (right only for a still camera). The shader also
   flips y with (1 - TexCoords.y) (a Direct3D texture convention copied from GPU Gems 3) in an
   OpenGL engine, and multiplies H * inverse(VP) (row-vector order; the transpose in GLSL unless the
   matrices were uploaded transposed). We reproject exactly: p = eye + depth * ray(x + .5, y + .5)
   with the current camera, projected by the previous camera (scenes.camera.CameraState), motion =
   current - previous in pixels (the study's convention), history read at (pixel - motion).
4. The [0, 1] clamps (minVal init 1, the sharpen's clamp) assume an 8-bit framebuffer; our colours
   are linear HDR, so the box is the plain min/max (identical on [0, 1] colours) and the sharpen
   (kernels.sharpen) clamps at 0 only.

Not specified by the seed, chosen here: off-screen reprojection (`offscreen='reject'`, default: the
pixel takes its current colour, as the baseline does; 'edge' reads the clamped edge texel as the
seed's texture() would); a point behind the previous camera counts as off-screen; the history is the
unsharpened blend and the sharpen (default 'none') is applied to the displayed output only.

Presets (registry):
  taa_ferrando_text          history_weight 0.95, clamp 'current' -- the text's 5 %, with the clamp
                             that does what the text says clamping is for
  taa_ferrando_code          history_weight 0.60, clamp 'history' -- the §5.5 shader as printed
                             (the clamp a no-op), motion sign and y fixed
  taa_ferrando_code_noclamp  history_weight 0.30, clamp 'none'    -- the §5.4 shader
All use camera-only motion from depth (their contract's `cameras`: Frame.cameras = (current, previous)).
`motion_source='buffer'` uses the frame's motion buffer instead (an ablation of that choice).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import array, dr, mi

from . import kernels as K
from .base import Frame, Inputs, check_sharpen, sharpen_weight
from .baseline import TAATechnique
from .contract import check_camera

CLAMPS = ("current", "history", "none")
MOTION_SOURCES = ("camera", "buffer")
OFFSCREEN = ("reject", "edge")


@dataclass(frozen=True)
class FerrandoParams:
    history_weight: float = 0.95     # k of out = mix(c, h, k) (the text's "5 %" of the new frame)
    clamp: str = "current"           # one of CLAMPS (module docstring, mistake 1)
    motion_source: str = "camera"    # 'camera': from depth + both cameras (Ferrando's); 'buffer'
    offscreen: str = "reject"        # one of OFFSCREEN
    sharpen: str | float = "none"    # a key of base.SHARPEN_KERNELS or a strength; Ferrando's optional one is 'xu'

    def __post_init__(self):
        k = float(self.history_weight)
        if not (0.0 <= k <= 1.0):
            raise ValueError(f"history_weight must be in [0, 1], got {self.history_weight!r}")
        object.__setattr__(self, "history_weight", k)
        for field, allowed in (("clamp", CLAMPS), ("motion_source", MOTION_SOURCES),
                               ("offscreen", OFFSCREEN)):
            if getattr(self, field) not in allowed:
                raise ValueError(f"{field} must be one of {allowed}, got {getattr(self, field)!r}")
        check_sharpen(self.sharpen)
        if not isinstance(self.sharpen, str):
            object.__setattr__(self, "sharpen", float(self.sharpen))


# ----------------------------------------------------------------------------- camera-only motion
def _reprojection(current, previous):
    """(G, b, tan_half of previous): the previous camera-space point of pixel position (X, Y) at
    depth z of the current camera is q = b + z * G (X, Y, 1) (float64 constants)."""
    tx, ty = current.tan_half
    W, H = current.width, current.height
    M = np.array([[2 * tx / W, 0.0, -tx], [0.0, -2 * ty / H, ty], [0.0, 0.0, -1.0]])  # -> d_cam
    R = np.asarray(current.to_world, float)[:3, :3]
    V = np.linalg.inv(np.asarray(previous.to_world, float))
    G = V[:3, :3] @ R @ M
    b = V[:3, :3] @ np.asarray(current.to_world, float)[:3, 3] + V[:3, 3]
    return G, b, previous.tan_half


def camera_motion(grid: K.Grid, depth, current, previous):
    """Motion (pixels, current - previous position) of the static surface point at each pixel
    centre, from the linear view depth and the two cameras; Vector2f. A point behind the previous
    camera gets a motion that puts its previous position far off-screen. Two identical cameras give
    exactly zero."""
    if (np.array_equal(current.to_world, previous.to_world) and current.yfov_deg == previous.yfov_deg
            and (current.width, current.height) == (previous.width, previous.height)):
        return dr.zeros(mi.Vector2f, grid.n)
    G, b, (ptx, pty) = _reprojection(current, previous)
    # opaque: the cameras change every frame, and literals would compile a kernel per frame
    f = K.opaque_float
    b = [f(v) for v in b]
    ptx, pty = K.opaque_rcp(ptx), K.opaque_rcp(pty)   # `* rcp` is what `/ literal` computed
    X = mi.Float(grid.x) + 0.5
    Y = mi.Float(grid.y) + 0.5
    g = [[f(v) for v in row] for row in G]
    qx = b[0] + depth * (g[0][0] * X + g[0][1] * Y + g[0][2])
    qy = b[1] + depth * (g[1][0] * X + g[1][1] * Y + g[1][2])
    zq = -(b[2] + depth * (g[2][0] * X + g[2][1] * Y + g[2][2]))
    ahead = zq > 0
    safe = dr.select(ahead, zq, 1.0)
    px = (qx / safe * ptx + 1.0) * f(0.5 * float(previous.width))
    py = (1.0 - qy / safe * pty) * f(0.5 * float(previous.height))
    far_off = f(4.0 * float(max(grid.w, grid.h)) + 4.0)
    return mi.Vector2f(dr.select(ahead, X - px, far_off), dr.select(ahead, Y - py, far_off))


def motion_from_depth(depth: np.ndarray, current, previous) -> np.ndarray:
    """NumPy convenience: (H, W, 2) float32 camera-only motion for an (H, W) depth buffer."""
    check_camera(current, "current")
    check_camera(previous, "previous")
    h, w = np.shape(depth)
    grid = K.Grid(w, h)
    v = camera_motion(grid, array(mi.Float, depth, np.float32), current, previous)
    return np.asarray(dr.ravel(v), np.float32).reshape(h, w, 2).copy()


# --------------------------------------------------------------------------------------- technique
class FerrandoTAA(TAATechnique):
    """Fixed-weight single-history TAA with a 3x3 min/max clamp (module docstring)."""
    name = "taa_ferrando"
    Params = FerrandoParams

    @classmethod
    def inputs_for(cls, params=None) -> Inputs:
        """Camera-only motion reads depth and both cameras; the ablation reads the motion buffer."""
        cam = (params if params is not None else cls.Params()).motion_source == "camera"
        return Inputs(buffers={"color", "depth"} if cam else {"color", "motion"}, sampling="sequence",
                      cameras=cam)

    def _step(self, b: dict, frame: Frame):
        p = self.params
        grid = self._grid_for(*frame.size)
        c = b["color"]
        if p.motion_source == "camera":
            velocity = camera_motion(grid, b["depth"], *frame.cameras)
        else:
            velocity = b["motion"]
        terms = {"velocity": velocity}
        if self._history is None:
            blend = c
            valid = None
        else:
            px, py, valid = K.previous_position(grid, velocity)
            hist = K.bilinear(grid, self._history, px, py)
            terms["history_raw"] = hist
            if p.clamp != "none":
                if p.clamp == "current":
                    nb = K.neighbourhood(grid, c)
                    lo, hi = nb.min3, nb.max3
                else:   # the seed's: 9 bilinear taps of the history around the reprojected point
                    lo = hi = None
                    for dx, dy in K.OFFSETS_3X3:
                        t = K.bilinear(grid, self._history, px + dx, py + dy)
                        lo = t if lo is None else dr.minimum(lo, t)
                        hi = t if hi is None else dr.maximum(hi, t)
                hist = dr.clip(hist, lo, hi)
                terms.update(clamp_min=lo, clamp_max=hi)
            blend = K.lerp(c, hist, p.history_weight)
            if p.offscreen == "reject":
                blend = dr.select(valid, blend, c)
        dr.eval(blend)
        self._history = blend
        terms["history_valid"] = (mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
                                  else dr.zeros(mi.Float, grid.n))
        terms["blend"] = blend
        self._terms = terms
        return K.sharpen(grid, blend, sharpen_weight(p.sharpen))


__all__ = ["FerrandoTAA", "FerrandoParams", "CLAMPS", "MOTION_SOURCES", "OFFSCREEN",
           "camera_motion", "motion_from_depth"]
