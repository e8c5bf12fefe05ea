"""Small procedural mesh builders for the built-in scenes (NumPy only, no assets).

Every builder returns a `MeshData` with per-vertex normals: flat pieces repeat their face normal
on unshared vertices (so they shade exactly as flat faces), curved pieces carry smooth normals.
`merge` joins pieces into one mesh; `surface_objects` splits a mesh into one scene object per
flat orientation plus one for the smooth (curved) faces.

Why split: the agreement check (study/agreement.py) compares raster and reference pixel centres
only in the interior of objects (3x3 equal object ids). A crease between two faces of one object
(a box's front and side) or an overlap of two parts of one mesh is a colour edge that object ids
do not see; a pixel centre within rasteriser precision of it may fall on different sides in the
two renderers. Making every crease an object boundary keeps that check meaningful. Shapes in
the x-y plane face +z.
"""
from __future__ import annotations

import numpy as np

from ..description import Material, MeshSpec, Motion, SceneObject, Transform
from ..meshes import MeshData
from ..meshes import box as _unit_box


def spec(m: MeshData) -> MeshSpec:
    return MeshSpec(kind="arrays", vertices=m.vertices, faces=m.faces, uvs=m.uvs, normals=m.normals)


def face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def oriented(m: MeshData) -> MeshData:
    """Winding turned, face by face, to agree with the vertex normals (shading flips normals
    towards the viewer using the geometric normal, so the two must point the same way)."""
    if m.normals is None:
        return m
    ng = face_normals(m.vertices, m.faces)
    ns = m.normals[m.faces].sum(axis=1)
    f = m.faces.copy()
    flip = np.sum(ng * ns, axis=1) < 0
    f[flip] = f[flip][:, [0, 2, 1]]
    return MeshData(m.vertices, f, m.uvs, m.normals)


def flat(v: np.ndarray, f: np.ndarray, uv: np.ndarray | None = None) -> MeshData:
    """Flat faces: vertices duplicated per face, each carrying its face's normal."""
    n = np.repeat(face_normals(v, f), 3, axis=0)
    return MeshData(v[f].reshape(-1, 3), np.arange(3 * len(f)).reshape(-1, 3),
                    None if uv is None else uv[f].reshape(-1, 2), n)


def merge(*parts: MeshData) -> MeshData:
    """One mesh from several. UVs are kept if any part has them (zeros elsewhere); normals only if
    every part has them."""
    parts = [p for p in parts if p is not None]
    verts, faces, uvs, normals, base = [], [], [], [], 0
    for p in parts:
        verts.append(p.vertices)
        faces.append(p.faces + base)
        uvs.append(p.uvs if p.uvs is not None else np.zeros((len(p.vertices), 2)))
        normals.append(p.normals)
        base += len(p.vertices)
    any_uv = any(p.uvs is not None for p in parts)
    all_n = all(n is not None for n in normals)
    if not all_n and any(n is not None for n in normals):
        raise ValueError("merge: some parts have vertex normals and some do not")
    return MeshData(np.concatenate(verts), np.concatenate(faces),
                    np.concatenate(uvs) if any_uv else None, np.concatenate(normals) if all_n else None)


def rotation(axis, deg) -> np.ndarray:
    a = np.asarray(axis, float)
    x, y, z = a / np.linalg.norm(a)
    t = np.radians(deg)
    c, s, C = np.cos(t), np.sin(t), 1 - np.cos(t)
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def moved(m: MeshData, translate=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), deg: float = 0.0) -> MeshData:
    """Rotated about the origin, then translated."""
    r = rotation(axis, deg) if deg else np.eye(3)
    n = None if m.normals is None else m.normals @ r.T
    return MeshData(m.vertices @ r.T + np.asarray(translate, float), m.faces, m.uvs, n)


def box(size, at=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), deg: float = 0.0) -> MeshData:
    b = _unit_box(size)
    return moved(flat(b.vertices, b.faces, b.uvs), at, axis, deg)


def rect(x0, x1, y0, y1, z=0.0) -> MeshData:
    """An axis-aligned rectangle in the plane z, facing +z, with UVs over [0,1]^2."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return MeshData(v, np.array([[0, 1, 2], [0, 2, 3]]), np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float),
                    np.tile([0.0, 0.0, 1.0], (4, 1)))


def strip(a: np.ndarray, b: np.ndarray, na: np.ndarray | None = None, nb: np.ndarray | None = None
          ) -> MeshData:
    """Quads between two polylines with the same number of points (a[i], a[i+1], b[i+1], b[i]).
    With normals na, nb (per point) the strip is smooth; without, every quad is flat."""
    n = len(a)
    v = np.concatenate([a, b]).astype(float)
    i = np.arange(n - 1)
    f = np.concatenate([np.stack([i, i + 1, n + i + 1], -1), np.stack([i, n + i + 1, n + i], -1)])
    if na is None:
        return flat(v, f)
    return oriented(MeshData(v, f, None, np.concatenate([na, nb]).astype(float)))


def arc(cx, cy, r, a0_deg, a1_deg, segments, z=0.0) -> np.ndarray:
    t = np.radians(np.linspace(a0_deg, a1_deg, segments + 1))
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t), np.full_like(t, z)], -1)


def _radial(a0_deg, a1_deg, segments, sign=1.0) -> np.ndarray:
    t = np.radians(np.linspace(a0_deg, a1_deg, segments + 1))
    return sign * np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], -1)


def arc_member(cx, cy, r_in, r_out, a0_deg, a1_deg, segments, z0, z1) -> MeshData:
    """A curved bar (an annulus sector extruded from z0 to z1): flat front and back faces, smooth
    inner and outer faces."""
    def ring(r, z):
        return arc(cx, cy, r, a0_deg, a1_deg, segments, z)
    n_in, n_out = _radial(a0_deg, a1_deg, segments, -1.0), _radial(a0_deg, a1_deg, segments)
    return merge(strip(ring(r_in, z1), ring(r_out, z1)), strip(ring(r_in, z0), ring(r_out, z0)),
                 strip(ring(r_in, z0), ring(r_in, z1), n_in, n_in),
                 strip(ring(r_out, z0), ring(r_out, z1), n_out, n_out))


def soffit(cx, cy, r, segments, z0, z1) -> MeshData:
    """The smooth underside of a semicircular arch from z0 to z1 (normals towards the centre)."""
    n = _radial(180.0, 0.0, segments, -1.0)
    return strip(arc(cx, cy, r, 180.0, 0.0, segments, z0), arc(cx, cy, r, 180.0, 0.0, segments, z1), n, n)


def spandrel(cx, cy, r, y_top, segments, z=0.0) -> MeshData:
    """The region of [cx-r, cx+r] x [cy, y_top] above a semicircle of radius r centred at (cx, cy):
    a wall over an arch. Facing +z."""
    curve = arc(cx, cy, r, 180.0, 0.0, segments, z)
    top = curve.copy()
    top[:, 1] = y_top
    nz = np.tile([0.0, 0.0, 1.0], (len(curve), 1))
    return strip(curve, top, nz, nz)


def wall_with_hole(x0, x1, y0, y1, hx0, hx1, hy0, hy1, z=0.0) -> MeshData:
    """A rectangle [x0,x1]x[y0,y1] with a rectangular hole [hx0,hx1]x[hy0,hy1]."""
    return merge(rect(x0, hx0, y0, y1, z), rect(hx1, x1, y0, y1, z),
                 rect(hx0, hx1, y0, hy0, z), rect(hx0, hx1, hy1, y1, z))


def tubes(paths: np.ndarray, radius: float, sides: int = 3) -> MeshData:
    """Open tubes with `sides`-gon cross-sections along polylines `paths` (F, K, 3), with smooth
    (radial) normals; the frame is parallel-transported along each path."""
    F, K, _ = paths.shape
    tang = np.gradient(paths, axis=1)
    tang /= np.linalg.norm(tang, axis=-1, keepdims=True)
    ref = np.where(np.abs(tang[:, 0, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    n = np.cross(tang[:, 0], ref)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normals = np.empty_like(paths)
    for k in range(K):
        n = n - np.sum(n * tang[:, k], -1, keepdims=True) * tang[:, k]
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        normals[:, k] = n
    binormals = np.cross(tang, normals)
    ang = 2 * np.pi * np.arange(sides) / sides
    radial = np.cos(ang)[None, None, :, None] * normals[:, :, None] + \
        np.sin(ang)[None, None, :, None] * binormals[:, :, None]          # (F, K, S, 3)
    verts = paths[:, :, None] + radius * radial
    fi, ki, si = np.meshgrid(np.arange(F), np.arange(K - 1), np.arange(sides), indexing="ij")

    def vid(f, k, s):
        return (f * K + k) * sides + s % sides
    a, b = vid(fi, ki, si), vid(fi, ki, si + 1)
    c, d = vid(fi, ki + 1, si + 1), vid(fi, ki + 1, si)
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return oriented(MeshData(verts.reshape(-1, 3), faces.astype(np.int64), None, radial.reshape(-1, 3)))


def _subset(m: MeshData, faces: np.ndarray) -> MeshData:
    used, inv = np.unique(faces.ravel(), return_inverse=True)
    return MeshData(m.vertices[used], inv.reshape(-1, 3), None if m.uvs is None else m.uvs[used],
                    None if m.normals is None else m.normals[used])


def surfaces(m: MeshData) -> list[MeshData]:
    """Faces grouped into surfaces without creases: one group per flat orientation (faces whose
    vertex normals all equal their face normal), and one for the smooth faces."""
    ng = face_normals(m.vertices, m.faces)
    vn = m.normals[m.faces]                                  # (F, 3, 3)
    is_flat = np.all(np.abs(vn - ng[:, None]) < 1e-6, axis=(1, 2)) | \
        np.all(np.abs(vn + ng[:, None]) < 1e-6, axis=(1, 2))
    keys = [("smooth",) if fl else None for fl in ~is_flat]
    rounded = np.round(np.where((ng @ [1e-3, 1e-2, 1.0])[:, None] < 0, -ng, ng), 4) + 0.0
    groups: dict = {}
    for i in range(len(m.faces)):
        k = keys[i] or tuple(rounded[i])
        groups.setdefault(k, []).append(i)
    order = sorted(groups, key=lambda k: (k == ("smooth",), k if k != ("smooth",) else ()))
    return [_subset(m, m.faces[groups[k]]) for k in order]


def surface_objects(name: str, m: MeshData, material: Material, transform: Transform = Transform(),
                    motion: Motion = Motion()) -> list[SceneObject]:
    """One scene object per crease-free surface of `m` (see `surfaces`), named name_0, name_1..."""
    parts = surfaces(m)
    return [SceneObject(name=f"{name}_{i}" if len(parts) > 1 else name, mesh=spec(p), material=material,
                        transform=transform, motion=motion) for i, p in enumerate(parts)]
