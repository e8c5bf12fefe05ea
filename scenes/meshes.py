"""Triangle meshes: built in code or loaded from OBJ/PLY/glTF. Vertices are duplicated per face
where UVs or normals are discontinuous, so every attribute is per vertex."""
from __future__ import annotations

import codecs
import io
import os
import warnings
from dataclasses import dataclass

import numpy as np

from .description import MeshSpec


class SceneError(ValueError):
    """A scene description or one of its assets is invalid; the message names the culprit."""


class SceneWarning(UserWarning):
    """Something in a scene is suspect but renderable (e.g. some zero-area triangles)."""


# A triangle whose doubled area is below this fraction of its longest edge squared is a line or a
# point: float64 rounding of exactly collinear vertices gives ~1e-16, a visible sliver far more.
DEGENERATE_REL = 1e-12


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Boolean mask of the faces with (numerically) zero area."""
    t = vertices[faces]
    e1, e2, e3 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], t[:, 2] - t[:, 1]
    area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest2 = np.max([np.einsum("ij,ij->i", e, e) for e in (e1, e2, e3)], axis=0)
    return area2 <= DEGENERATE_REL * longest2


@dataclass(frozen=True)
class MeshData:
    vertices: np.ndarray            # (V, 3) float64, object space
    faces: np.ndarray               # (F, 3) int64
    uvs: np.ndarray | None = None   # (V, 2)
    normals: np.ndarray | None = None  # (V, 3) for smooth shading; None = flat (face normals)
    tangents: np.ndarray | None = None  # (V, 4) unit dP/du and handedness w (glTF TANGENT), for normal maps

    def validate(self, where: str) -> "MeshData":
        v, f = self.vertices, self.faces
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise SceneError(f"{where}: vertices must have shape (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise SceneError(f"{where}: faces must have shape (F, 3), got {f.shape}")
        if not np.all(np.isfinite(v)):
            raise SceneError(f"{where}: vertices contain NaN or Inf")
        if f.min() < 0 or f.max() >= len(v):
            raise SceneError(f"{where}: face index out of range [0, {len(v)})")
        for name, a, k in (("uvs", self.uvs, 2), ("normals", self.normals, 3), ("tangents", self.tangents, 4)):
            if a is not None and (a.shape != (len(v), k) or not np.all(np.isfinite(a))):
                raise SceneError(f"{where}: {name} must be finite with shape ({len(v)}, {k})")
        bad = degenerate_faces(v, f)
        if bad.all():
            raise SceneError(f"{where}: all {len(f)} triangles are degenerate (zero area), "
                             "so the object would not be drawn")
        if bad.any():
            warnings.warn(f"{where}: {int(bad.sum())} of {len(f)} triangles are degenerate "
                          "(zero area) and cover no pixel", SceneWarning, stacklevel=2)
        return self


def quad(size=(1.0, 1.0), uv_scale=(1.0, 1.0)) -> MeshData:
    """A plane in x-y facing +z, centred at the origin."""
    sx, sy = size[0] / 2, size[1] / 2
    v = np.array([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) * uv_scale
    return MeshData(v, np.array([[0, 1, 2], [0, 2, 3]]), uv)


def box(size=(1.0, 1.0, 1.0), uv_scale=(1.0, 1.0)) -> MeshData:
    half = np.asarray(size, float) / 2
    verts, faces, uvs = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3); n[axis] = sign
            u = np.zeros(3); u[(axis + 1) % 3] = 1.0
            w = np.cross(n, u)
            base = len(verts)
            for cu, cw in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                verts.append((n + cu * u + cw * w) * half)
                uvs.append(((cu + 1) / 2 * uv_scale[0], (cw + 1) / 2 * uv_scale[1]))
            faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return MeshData(np.array(verts), np.array(faces), np.array(uvs))


def sphere(radius=0.5, segments=32, smooth=True, uv_scale=(1.0, 1.0)) -> MeshData:
    rings, sectors = segments // 2 + 1, segments + 1
    th = np.linspace(0, np.pi, rings)[:, None]
    ph = np.linspace(0, 2 * np.pi, sectors)[None, :]
    n = np.stack([np.sin(th) * np.cos(ph), np.cos(th) * np.ones_like(ph), np.sin(th) * np.sin(ph)], -1)
    n = n.reshape(-1, 3)
    uv = np.stack(np.meshgrid(np.linspace(0, 1, sectors), np.linspace(1, 0, rings)), -1).reshape(-1, 2)
    faces = []
    for r in range(rings - 1):
        for s in range(sectors - 1):
            a, b = r * sectors + s, (r + 1) * sectors + s
            if r > 0:
                faces.append([a, a + 1, b])
            if r < rings - 2:
                faces.append([a + 1, b + 1, b])
    return MeshData(n * radius, np.array(faces), uv * uv_scale, n if smooth else None)


def cylinder(radius=0.5, height=1.0, segments=32, smooth=True, uv_scale=(1.0, 1.0)) -> MeshData:
    """An open tube along y (a pipe), centred at the origin."""
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    ring = np.stack([np.cos(ph), np.zeros_like(ph), np.sin(ph)], -1)
    v = np.concatenate([ring * radius + [0, -height / 2, 0], ring * radius + [0, height / 2, 0]])
    uv = np.concatenate([np.stack([ph / (2 * np.pi), np.zeros_like(ph)], -1),
                         np.stack([ph / (2 * np.pi), np.ones_like(ph)], -1)]) * uv_scale
    k = segments + 1
    faces = [[i, i + 1, k + i + 1] for i in range(segments)] + [[i, k + i + 1, k + i] for i in range(segments)]
    return MeshData(v, np.array(faces), uv, np.concatenate([ring, ring]) if smooth else None)


def load_file(path: str, smooth: bool, base_dir: str | None, where: str = "mesh") -> MeshData:
    import trimesh
    full = path if os.path.isabs(path) or base_dir is None else os.path.join(base_dir, path)
    if not os.path.isfile(full):
        raise SceneError(f"{where}: mesh file not found: {full}")
    try:
        # trimesh decodes text formats as UTF-8 and falls back on charset-normalizer's guess, so
        # an OBJ written in Latin-1 or cp1252 (a byte >= 0x80 in a comment or a name) loads too.
        # A UTF-8 byte-order mark would survive that decoding and hide the first line's keyword.
        with open(full, "rb") as fh:
            bom = fh.read(3) == codecs.BOM_UTF8
        if bom and full.lower().endswith(".obj"):
            with open(full, "rb") as fh:
                body = io.BytesIO(fh.read()[3:])
            loaded = trimesh.load(body, file_type="obj", force="mesh", process=False,
                                  resolver=trimesh.resolvers.FilePathResolver(full))
        else:
            loaded = trimesh.load(full, force="mesh", process=False)
    except Exception as exc:
        raise SceneError(f"{where}: cannot read mesh file {full}: {exc}") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise SceneError(f"{where}: mesh file {full} holds no triangles")
    uv = getattr(loaded.visual, "uv", None)
    uv = None if uv is None or len(uv) != len(loaded.vertices) else np.asarray(uv, float)
    normals = np.asarray(loaded.vertex_normals, float) if smooth else None
    return MeshData(np.asarray(loaded.vertices, float), np.asarray(loaded.faces, np.int64), uv, normals)


def build(spec: MeshSpec, where: str, base_dir: str | None = None) -> MeshData:
    k = spec.kind
    if k == "box":
        m = box(spec.size, spec.uv_scale)
    elif k == "plane":
        m = quad(spec.size[:2], spec.uv_scale)
    elif k == "sphere":
        m = sphere(spec.radius, spec.segments, spec.smooth, spec.uv_scale)
    elif k == "cylinder":
        m = cylinder(spec.size[0], spec.size[1], spec.segments, spec.smooth, spec.uv_scale)
    elif k == "gltf":
        raise SceneError(f"{where}: a 'gltf' mesh is a whole scene; ResolvedScene expands it into objects")
    elif k == "file":
        m = load_file(spec.path, spec.smooth, base_dir, where)
        where = f"{where} (file {spec.path})"
    else:
        m = MeshData(np.asarray(spec.vertices, float), np.asarray(spec.faces, np.int64),
                     None if spec.uvs is None else np.asarray(spec.uvs, float),
                     None if spec.normals is None else np.asarray(spec.normals, float))
    return m.validate(where)
