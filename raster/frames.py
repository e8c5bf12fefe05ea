"""Per-frame buffers from the visibility pass: each pixel's one sample is rebuilt exactly
(ray-triangle intersection with the triangle the rasteriser found) and shaded by shading.shade,
the function the reference uses. Only the buffers asked for are computed.

Buffers (row-major (H, W, ...), origin top-left):
  color      float32 (H,W,3) linear HDR, the jittered sample
  albedo     float32 (H,W,3) unlit albedo (background colour where nothing is hit)
  depth      float32 (H,W)   linear view depth, world units (camera far plane for background)
  object_id  int32   (H,W)   1-based object index, 0 = background
  prim_id    int32   (H,W)   triangle index within the object, -1 = background
  normal     float32 (H,W,3) world shading normal facing the viewer (0 for background)
  motion     float32 (H,W,2) pixels, current minus previous image position of the same surface
             point, jitter excluded; exact for camera motion and moving/rotating objects
  prev_depth float32 (H,W)   linear depth of the same surface point in the previous frame's camera
  light_mask int32   (H,W)   bit i set where light i reaches the surface (shadow edges); needs color
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from backend import array, dr, mi, opaque
from scenes import ResolvedScene
from scenes.camera import CameraState
from shading import Surface, albedo_at, frame_geometry, shade

from .visibility import RasterError, VisibilityPass

BUFFERS = ("color", "albedo", "depth", "object_id", "prim_id", "normal", "motion", "prev_depth",
           "light_mask")


def _vec(m: np.ndarray, col: int) -> mi.Vector3f:
    return opaque(mi.Vector3f, *m[:3, col])


def image_position(cam: CameraState, p: mi.Point3f):
    """Unjittered image position (x right, y down, pixels) and view depth of world points."""
    d = p - _vec(cam.to_world, 3)
    x, y, z = (dr.dot(d, _vec(cam.to_world, k)) for k in range(3))
    depth = -z
    tx, ty = (opaque(mi.Float, v) for v in cam.tan_half)
    return mi.Point2f((x / depth / tx + 1) * 0.5 * cam.width, (1 - y / depth / ty) * 0.5 * cam.height), depth


def _direction_position(cam: CameraState, d: mi.Vector3f) -> mi.Point2f:
    """Image position of a direction (a point at infinity): background motion is rotation only."""
    x, y, z = (dr.dot(d, _vec(cam.to_world, k)) for k in range(3))
    tx, ty = (opaque(mi.Float, v) for v in cam.tan_half)
    return mi.Point2f((x / -z / tx + 1) * 0.5 * cam.width, (1 - y / -z / ty) * 0.5 * cam.height)


@dataclass(frozen=True)
class FrustumCamera(CameraState):
    """A camera whose frustum has the aspect of another image: an upscaler renders at a fraction of
    the output's size, over the output's frustum, so its render pixels may be a little off square.
    (Here, not in scenes.camera: references key on the scenes package's code and need no change.)"""
    aspect: float = 1.0

    @property
    def tan_half(self) -> tuple[float, float]:
        ty = float(np.tan(np.radians(self.yfov_deg) / 2))
        return ty * self.aspect, ty


def _gather3(arr: mi.Float, i) -> mi.Vector3f:
    return dr.gather(mi.Vector3f, arr, i)


def _ray_dir(cam: CameraState, sx, sy) -> mi.Vector3f:
    """Direction of the camera ray through image position (sx, sy), pixels."""
    tx, ty = (opaque(mi.Float, v) for v in cam.tan_half)
    return (_vec(cam.to_world, 0) * ((2 * sx / cam.width - 1) * tx)
            + _vec(cam.to_world, 1) * ((1 - 2 * sy / cam.height) * ty) - _vec(cam.to_world, 2))


def _plane_uv(ray_o, ray_d, v0, e1, e2, uvs):
    """UV where a ray meets the plane of triangle (v0, v0 + e1, v0 + e2), barycentrics extrapolated
    beyond its edges (Moller-Trumbore without the inside test)."""
    pvec = dr.cross(ray_d, e2)
    inv = dr.rcp(dr.dot(e1, pvec))
    tvec = ray_o - v0
    b1 = dr.dot(tvec, pvec) * inv
    b2 = dr.dot(ray_d, dr.cross(tvec, e1)) * inv
    return uvs[0] * (1 - b1 - b2) + uvs[1] * b1 + uvs[2] * b2


def uv_footprint(cam: CameraState, sx, sy, v0, e1, e2, uvs):
    """(du/dx, dv/dx, du/dy, dv/dy) of the triangle's UV per pixel at image position (sx, sy):
    central differences of the UV where the rays half a pixel either side meet the triangle's
    plane, computed analytically from the triangle (not from neighbouring pixels, which may hold
    other triangles; a GPU's 2x2-quad derivatives are the one-pixel forward difference of this)."""
    ray_o = opaque(mi.Point3f, *cam.position)
    at = lambda dx, dy: _plane_uv(ray_o, _ray_dir(cam, sx + dx, sy + dy), v0, e1, e2, uvs)   # noqa: E731
    ddx, ddy = at(0.5, 0.0) - at(-0.5, 0.0), at(0.0, 0.5) - at(0.0, -0.5)
    return ddx.x, ddx.y, ddy.x, ddy.y


class Rasterizer:
    """Renders frames of one scene at one resolution; holds the GL context. `aspect`: the frustum's
    width / height when it is not the image's (a render at an upscaler's fraction of the output
    keeps the output's frustum). `lod_bias`: added to every trilinear texture's level of detail
    (docs/method.md, "Texture filtering"); `mipmaps=False` samples their base level bilinearly
    instead (the agreement check's raster). Scenes without filtered textures ignore both."""

    def __init__(self, scene: ResolvedScene, width: int, height: int, aspect: float | None = None,
                 lod_bias: float = 0.0, mipmaps: bool = True):
        if not np.isfinite(lod_bias):
            raise RasterError(f"lod_bias must be a finite number, got {lod_bias!r}")
        self.scene, self.width, self.height, self.aspect = scene, width, height, aspect
        self.lod_bias, self.mipmaps = float(lod_bias), bool(mipmaps)
        self.vis = VisibilityPass(width, height)
        self._geo_cache: tuple | None = None
        self._static = all(scene.is_static(i) for i in range(len(scene.meshes)))
        self._ss_memo: tuple = (None, {})     # supersample's passes and shaded pixels of one scene time

    @property
    def samples_per_pixel(self) -> int:
        return self.vis.samples_per_pixel

    def camera(self, t: int) -> CameraState:
        cam = self.scene.camera(t, self.width, self.height)
        if self.aspect is None:
            return cam
        return FrustumCamera(**{f.name: getattr(cam, f.name) for f in dataclasses.fields(cam)}, aspect=self.aspect)

    def geometry(self, t: int):
        key = 0 if self._static else t
        if self._geo_cache is None or self._geo_cache[0] != key:
            self._geo_cache = (key, frame_geometry(self.scene, t))
        return self._geo_cache[1]

    def _prev_positions(self, prev_t: int) -> mi.Float:
        return array(mi.Float, np.concatenate([self.scene.world_vertices(i, prev_t)
                                               for i in range(len(self.scene.meshes))]), np.float32)

    def _reconstruct(self, geo, cam: CameraState, idx: mi.UInt32, obj_ids: np.ndarray, prims: np.ndarray, jitter):
        """Rebuild the surface each pixel's sample hit: the camera ray through the jittered sample
        intersected (Moller-Trumbore) with the triangle the visibility pass found there, and, where
        a texture is trilinear, its UV footprint there (uv_footprint) with this raster's LOD bias.
        `idx` are pixel indices y*W + x; obj_ids/prims hold their ids."""
        W, H = cam.width, cam.height
        sx = mi.Float(idx % W) + 0.5 + opaque(mi.Float, jitter[0])
        sy = mi.Float(idx // W) + 0.5 + opaque(mi.Float, jitter[1])
        tx, ty = (opaque(mi.Float, v) for v in cam.tan_half)
        ray_d = (_vec(cam.to_world, 0) * ((2 * sx / W - 1) * tx) + _vec(cam.to_world, 1) * ((1 - 2 * sy / H) * ty)
                 - _vec(cam.to_world, 2))
        ray_o = opaque(mi.Point3f, *cam.position)
        obj = array(mi.UInt32, obj_ids, np.uint32)
        valid = obj > 0
        face_off = array(mi.UInt32, geo.face_offset, np.uint32)
        prim = array(mi.UInt32, prims, np.uint32)
        face = dr.gather(mi.UInt32, face_off, dr.maximum(obj, 1) - 1, valid) + prim
        i0, i1, i2 = (dr.gather(mi.UInt32, geo.faces, face * 3 + k, valid) for k in range(3))
        v0, v1, v2 = (_gather3(geo.positions, i) for i in (i0, i1, i2))
        e1, e2 = v1 - v0, v2 - v0
        pvec = dr.cross(ray_d, e2)
        det = dr.dot(e1, pvec)
        ok = valid & (dr.abs(det) > 1e-20)
        inv = dr.select(ok, dr.rcp(det), 0.0)
        tvec = ray_o - v0
        b1 = dr.select(ok, dr.dot(tvec, pvec) * inv, 1 / 3)
        qvec = dr.cross(tvec, e1)
        b2 = dr.select(ok, dr.dot(ray_d, qvec) * inv, 1 / 3)
        b0 = 1 - b1 - b2
        p = v0 * b0 + v1 * b1 + v2 * b2
        n_geo = dr.normalize(dr.cross(e1, e2))
        smooth = dr.gather(mi.Bool, geo.obj_smooth, obj, valid)
        n_interp = dr.normalize(_gather3(geo.vnormals, i0) * b0 + _gather3(geo.vnormals, i1) * b1
                                + _gather3(geo.vnormals, i2) * b2)
        n_sh = dr.select(smooth, n_interp, n_geo)
        uvs = [dr.gather(mi.Point2f, geo.uvs, i, valid) for i in (i0, i1, i2)]
        uv = uvs[0] * b0 + uvs[1] * b1 + uvs[2] * b2
        foot = None
        if self.mipmaps and geo.mips:
            foot = (uv_footprint(cam, sx, sy, v0, e1, e2, uvs), opaque(mi.Float, self.lod_bias))
        surf = Surface(obj=obj, p=p, n_geo=n_geo, n_sh=n_sh, uv=uv, prim=prim, foot=foot)
        return ray_d, surf, (i0, i1, i2, b0, b1, b2)

    def supersample(self, t: int, mask: np.ndarray, offsets, reuse: bool = True) -> tuple[np.ndarray, dict]:
        """Mean colour of extra samples at `offsets` (pixels), shaded only where `mask` is set.

        Every visibility pass covers the frame (it is cheap and writes ids only); reconstruction
        and shading run on the masked pixels alone (fragment culling). Returns the (H, W, 3) image
        (0 outside the mask) and counts: samples shaded, objects drawn vs needed (mesh culling).
        `reuse`: a sample is a function of (t, offset, pixel) alone, so the passes and shaded
        pixels of the last scene time are kept and a later call at that time (a static test's 256
        frames, a warm-up) computes only pixels not shaded yet: the same values (shading is per
        pixel); the counts are the technique's, not this cache's. reuse=False: the full work (the
        cost measurement's)."""
        W, H = self.width, self.height
        mask = np.asarray(mask, bool)
        if mask.shape != (H, W):
            raise RasterError(f"supersample mask has shape {mask.shape}, expected {(H, W)}")
        sel = np.flatnonzero(mask)
        out = np.zeros((H * W, 3), np.float64)
        needed: set[int] = set()
        if len(sel):
            if not reuse or self._ss_memo[0] != t:
                self._ss_memo = (t if reuse else None, {})
            memo = self._ss_memo[1]
            cam, geo = self.camera(t), self.geometry(t)      # both cheap; geometry is cached per time
            for jit in offsets:
                key = (round(float(jit[0]), 9), round(float(jit[1]), 9))
                if key not in memo:
                    obj_np, prim_np = self.vis.render(self.scene, t, cam.view(), cam.projection(jit))
                    memo[key] = (obj_np.ravel(), prim_np.ravel(), np.zeros((H * W, 3), np.float32),
                                 np.zeros(H * W, bool))
                obj, prim, col, done = memo[key]
                needed.update(int(v) for v in np.unique(obj[sel]) if v > 0)
                todo = sel[~done[sel]]
                if len(todo):
                    idx = array(mi.UInt32, todo, np.uint32)
                    _, surf, _ = self._reconstruct(geo, cam, idx, obj[todo], prim[todo], jit)
                    c = shade(geo, surf, cam.position, surf.obj > 0)
                    dr.eval(c)               # one kernel for the three channels
                    col[todo] = np.stack([np.asarray(c[k]) for k in range(3)], -1)
                    done[todo] = True
                out[sel] += col[sel]
            out[sel] /= len(offsets)
        stats = {"samples_shaded": int(len(sel) * len(offsets)), "pixels_supersampled": int(len(sel)),
                 "objects_needed": len(needed), "objects_total": len(self.scene.meshes)}
        return out.reshape(H, W, 3).astype(np.float32), stats

    def render(self, t: int, jitter=(0.0, 0.0), buffers=("color",), prev_t: int | None = None
               ) -> dict[str, np.ndarray]:
        """Buffers of scene time t. Motion and prev_depth refer to scene time `prev_t` (default
        t - 1): the time of the frame the technique saw before, which for a static test (many
        frames of one instant) is t itself."""
        prev_t = t - 1 if prev_t is None else prev_t
        unknown = set(buffers) - set(BUFFERS)
        if unknown:
            raise RasterError(f"unknown buffer(s) {sorted(unknown)}; available: {BUFFERS}")
        W, H = self.width, self.height
        cam = self.camera(t)
        obj_np, prim_np = self.vis.render(self.scene, t, cam.view(), cam.projection(jitter))
        geo = self.geometry(t)
        n_obj = geo.n_objects
        if obj_np.max() > n_obj:
            raise RasterError(f"visibility pass returned object id {obj_np.max()} > {n_obj}")

        idx = dr.arange(mi.UInt32, W * H)
        ray_d, surf, (i0, i1, i2, b0, b1, b2) = self._reconstruct(geo, cam, idx, obj_np.ravel(), prim_np.ravel(),
                                                                 jitter)
        obj, p, n_geo, n_sh, uv = surf.obj, surf.p, surf.n_geo, surf.n_sh, surf.uv
        valid = obj > 0
        eye = cam.position
        # every buffer asked for is evaluated in one kernel launch: converting a Color3f channel by
        # channel launched (and compiled) the whole shading once per channel, and depth, motion
        # and normal once more each
        lazy: dict = {}                    # buffer -> (Dr.Jit value, channels)
        if "color" in buffers or "light_mask" in buffers:
            masks: list = []
            colour = shade(geo, surf, eye, valid, light_mask=masks)
            if "color" in buffers:
                lazy["color"] = (colour, 3)
            if "light_mask" in buffers:
                lazy["light_mask"] = (masks[0], 1)
        if "albedo" in buffers:
            bg = opaque(mi.Color3f, *self.scene.desc.background)
            lazy["albedo"] = (dr.select(valid, albedo_at(geo, obj, uv, valid, surf.foot), bg), 3)
        if "depth" in buffers or "motion" in buffers:
            pos_cur, depth = image_position(cam, p)
        if "depth" in buffers:
            lazy["depth"] = (dr.select(valid, depth, opaque(mi.Float, cam.far)), 1)
        if "normal" in buffers:
            facing = dr.select(dr.dot(n_geo, p - opaque(mi.Point3f, *eye)) > 0, -n_sh, n_sh)
            lazy["normal"] = (dr.select(valid, facing, 0.0), 3)
        if "motion" in buffers or "prev_depth" in buffers:
            prev_cam = self.camera(prev_t)
            pp = self._prev_positions(prev_t)
            p_prev = _gather3(pp, i0) * b0 + _gather3(pp, i1) * b1 + _gather3(pp, i2) * b2
            pos_prev, depth_prev = image_position(prev_cam, p_prev)
            if "motion" in buffers:
                bg_now = _direction_position(cam, ray_d)
                bg_prev = _direction_position(prev_cam, ray_d)
                lazy["motion"] = (dr.select(valid, pos_cur - pos_prev, bg_now - bg_prev), 2)
            if "prev_depth" in buffers:
                lazy["prev_depth"] = (dr.select(valid, depth_prev, opaque(mi.Float, prev_cam.far)), 1)
        dr.eval(*(v for v, _ in lazy.values()))

        out: dict[str, np.ndarray] = {}
        for name, (x, c) in lazy.items():
            if name == "light_mask":
                out[name] = np.asarray(x, np.int64).reshape(H, W).astype(np.int32)
            elif c == 1:
                out[name] = np.asarray(x, dtype=np.float32).reshape(H, W)
            else:
                out[name] = np.stack([np.asarray(x[k]) for k in range(c)], -1).reshape(H, W, c)
        if "object_id" in buffers:
            out["object_id"] = obj_np.astype(np.int32)
        if "prim_id" in buffers:
            out["prim_id"] = np.where(obj_np > 0, prim_np.astype(np.int64), -1).astype(np.int32)
        for name, a in out.items():
            if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                bad = int(np.count_nonzero(~np.isfinite(a)))
                raise RasterError(f"scene {self.scene.name!r} frame {t}: buffer {name!r} has "
                                  f"{bad} NaN/Inf values")
        return out

    def close(self):
        self.vis.close()
