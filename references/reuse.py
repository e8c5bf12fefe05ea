"""Which pixels of frame t's reference are the previous frame's: a conservative geometric test.

Where the camera is still and nothing changes globally, a pixel that no moving object, nor the
shadow of one, reaches at frame t - 1, at frame t or in between sees the same scene in both frames:
its converged value is the same, and the previous frame's estimate of it (its value, its halves and
its sample counts) is an estimate of this frame's as well (references.render, `reuse`). The test
looks only at the scene's description, never at images:

  - the frame's global state: a hard cut, a camera that moved, or a scene whose light reaches
    every pixel through other surfaces (transport 'path') while anything moves disable reuse for
    the frame (lights, materials and emitters are constant over a scene's frames in this
    description: only object poses and the camera move);
  - each moving object's volume swept over [t - 1, t], as points whose convex hull holds it: a
    translating object's world bounding box at both frames (it moves linearly, so the box in
    between lies in their union); a spinning one's bounding sphere about its own origin (the spin
    keeps every vertex's distance from it), whose centre moves linearly: the capsule between the
    two frames' spheres, held by the hull of a polyhedron circumscribing each sphere;
  - with shadows (transport 'direct_shadows'), the shadow volume of that hull from each light: for
    a directional light the hull extruded along the light's direction by the diagonal of the
    receivers' bounds (every object at both frames: no receiver is farther); for a point light the
    hull scaled about the light by the ratio of the receivers' farthest corner to the nearest point
    of the hull's box (every point beyond the hull along a ray from the light, up to the receivers,
    lies in the hull of it and that scaled copy); a light inside the hull's box disables reuse;
  - each such convex hull, clipped at half the near plane (its part behind the camera projects to
    nothing; where its edges cross the plane is kept), projected to a pixel rectangle, widened to
    whole pixels (a reference pixel integrates its own square) and dilated by `margin` pixels:
    one for the 3x3 window the reference's unseen-feature floor reads (a reused pixel's floor and
    decisions saw only unchanged neighbours), one for rounding in the ray generation.
"""
from __future__ import annotations

import functools
import itertools

import numpy as np
from scipy.spatial import ConvexHull

from scenes import ResolvedScene

MARGIN = 2


def moving_objects(scene: ResolvedScene, t: int) -> list[int]:
    """Objects whose pose at frame t differs from frame t - 1's."""
    return [i for i in range(len(scene.desc.objects))
            if not np.array_equal(scene.object_pose(i, t - 1), scene.object_pose(i, t))]


def global_change(scene: ResolvedScene, t: int, width: int, height: int) -> str | None:
    """Why frame t's reference can reuse nothing of frame t - 1's (None: it may)."""
    if t <= 0:
        return "the first frame"
    if scene.is_cut(t):
        return "a camera cut"
    if not np.array_equal(scene.camera(t - 1, width, height).to_world, scene.camera(t, width, height).to_world):
        return "the camera moves"
    if scene.desc.transport == "path" and moving_objects(scene, t):
        return "transport 'path': a moving object's light reaches every pixel"
    return None


def _aabb(points: np.ndarray) -> np.ndarray:
    return np.stack([points.min(axis=0), points.max(axis=0)])


@functools.cache
def _circumscribed(n: int = 96) -> np.ndarray:
    """(n, 3) points whose convex hull holds the unit ball: Fibonacci directions scaled by the
    inverse of their hull's inradius (its nearest facet plane), so the bound is exact, not a guess."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    u = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)
    inradius = float(-ConvexHull(u).equations[:, 3].max())     # facets: n.x + d <= 0 inside
    return u / inradius * (1 + 1e-9)


def swept_points(scene: ResolvedScene, i: int, t: int) -> np.ndarray:
    """World points whose convex hull holds object i at every time in [t - 1, t]."""
    o = scene.desc.objects[i]
    if not o.motion.spin_deg:
        return _corners(_aabb(np.concatenate([scene.world_vertices(i, t - 1), scene.world_vertices(i, t)])))
    p0, p1 = scene.object_pose(i, t - 1), scene.object_pose(i, t)
    # the spin about the object's origin keeps each vertex's distance from it
    r = float(np.linalg.norm(scene.meshes[i].vertices @ p0[:3, :3].T, axis=1).max())
    ball = _circumscribed() * r
    return np.concatenate([p0[:3, 3] + ball, p1[:3, 3] + ball])


def swept_box(scene: ResolvedScene, i: int, t: int) -> np.ndarray:
    """(2, 3) world box holding object i at every time in [t - 1, t]."""
    return _aabb(swept_points(scene, i, t))


def _corners(box: np.ndarray) -> np.ndarray:
    return np.array([[box[a, 0], box[b, 1], box[c, 2]] for a, b, c in itertools.product((0, 1), repeat=3)])


def shadow_points(hull: np.ndarray, light, receivers: np.ndarray) -> np.ndarray | None:
    """Points whose convex hull holds the shadow volume of the hull of `hull` (points) from `light`
    up to the receivers' bounds (with the hull itself); None where the light is inside the hull's
    box (it may shadow anything)."""
    c, box = hull, _aabb(hull)
    world = np.stack([np.minimum(box[0], receivers[0]), np.maximum(box[1], receivers[1])])
    if light.type == "directional":
        d = np.asarray(light.direction, float)
        d /= np.linalg.norm(d)
        reach = float(np.linalg.norm(world[1] - world[0]))
        return np.concatenate([c, c + reach * d])
    p = np.asarray(light.position, float)
    near = float(np.linalg.norm(p - np.clip(p, box[0], box[1])))
    if near <= 1e-9 * max(1.0, float(np.abs(box).max())):
        return None
    far = float(np.linalg.norm(_corners(world) - p, axis=1).max())
    s = max(far / near, 1.0) * (1 + 1e-6)
    return np.concatenate([c, p + s * (c - p)])


def hull_rect(cam, points: np.ndarray) -> tuple[float, float, float, float] | None:
    """Image-space bounds (x0, y0, x1, y1) of the convex hull of world `points` in front of half the
    camera's near plane; None where none of it is."""
    view = cam.view()
    pc = points @ view[:3, :3].T + view[:3, 3]
    depth = -pc[:, 2]
    plane = 0.5 * cam.near
    front, back = depth >= plane, depth < plane
    kept = [pc[front]]
    if front.any() and back.any():
        # the hull's section by the plane: the hull of where segments between the sides cross it
        a, b = pc[front][:, None], pc[back][None]
        da, db = depth[front][:, None, None], depth[back][None, :, None]
        kept.append(((a + (b - a) * (da - plane) / (da - db))).reshape(-1, 3))
    q = np.concatenate(kept)
    if not len(q):
        return None
    d = np.maximum(-q[:, 2], plane)
    tx, ty = cam.tan_half
    x = (q[:, 0] / d / tx + 1) * 0.5 * cam.width
    y = (1 - q[:, 1] / d / ty) * 0.5 * cam.height
    return float(x.min()), float(y.min()), float(x.max()), float(y.max())


def changed_pixels(scene: ResolvedScene, t: int, width: int, height: int, margin: int = MARGIN,
                   shadows: bool = True, dilate: bool = True) -> np.ndarray | None:
    """(H, W) bool: pixels a moving object or its shadow may reach between frames t - 1 and t,
    dilated (see the module docstring); None where the whole frame may change (`global_change`,
    or a light inside a moving box). `shadows`/`dilate` exist for tests that break the test."""
    if global_change(scene, t, width, height) is not None:
        return None
    out = np.zeros((height, width), bool)
    moving = moving_objects(scene, t)
    if not moving:
        return out
    cam = scene.camera(t, width, height)
    swept = [swept_points(scene, i, t) for i in moving]
    receivers = _aabb(np.concatenate([scene.world_vertices(i, s) for i in range(len(scene.desc.objects))
                                      for s in (t - 1, t)] + swept))
    hulls = []
    for hull in swept:
        hulls.append(hull)
        if shadows and scene.desc.transport == "direct_shadows":
            for light in scene.desc.lights:
                pts = shadow_points(hull, light, receivers)
                if pts is None:
                    return None
                hulls.append(pts)
    m = margin if dilate else 0
    for pts in hulls:
        r = hull_rect(cam, pts)
        if r is None:
            continue
        x0, y0, x1, y1 = r
        if not np.all(np.isfinite(r)):
            return None
        xa, ya = int(np.floor(max(x0, -1e9))) - m, int(np.floor(max(y0, -1e9))) - m
        # pixel x covers [x, x + 1): the one holding x1 itself too
        xb, yb = int(np.floor(min(x1, 1e9))) + 1 + m, int(np.floor(min(y1, 1e9))) + 1 + m
        out[max(ya, 0):max(min(yb, height), 0), max(xa, 0):max(min(xb, width), 0)] = True
    return out


def reuse_mask(scene: ResolvedScene, t: int, width: int, height: int, **kw) -> np.ndarray | None:
    """(H, W) bool: pixels whose reference at frame t may be frame t - 1's; None: none may."""
    changed = changed_pixels(scene, t, width, height, **kw)
    return None if changed is None else ~changed
