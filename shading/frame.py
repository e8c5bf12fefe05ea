"""One frame's geometry in world space, as Dr.Jit tables and as a Mitsuba scene.

World-space vertices are computed once here in float64 and rounded to float32, so the raster's
surface reconstruction and Mitsuba's ray tracer intersect exactly the same triangles.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from backend import dr, mi
from scenes import ResolvedScene


@dataclass
class FrameGeometry:
    scene: ResolvedScene
    frame: int
    positions: mi.Float       # world vertices, flat xyz
    vnormals: mi.Float        # world vertex normals, flat xyz (zero for flat-shaded objects)
    uvs: mi.Float             # flat uv (zero where a mesh has none)
    faces: mi.UInt32          # global vertex indices, flat
    face_offset: np.ndarray   # first global face of each object (n_objects + 1)
    obj_smooth: mi.Bool       # per object id (index 0 = background)
    obj_albedo: mi.Float      # per object id, flat rgb
    obj_emission: mi.Float    # per object id, flat rgb
    has_emission: bool
    obj_tex: mi.UInt32        # per object id: offset, width, height into tex_data (width 0 = none)
    tex_data: mi.Float
    obj_alpha: mi.UInt32      # per object id: offset, width, height into alpha_data (width 0 = none)
    obj_alpha_threshold: mi.Float
    alpha_data: mi.Float
    has_alpha: bool
    mitsuba: object           # mi.Scene with the same triangles; face attribute face_objid

    @property
    def n_objects(self) -> int:
        return len(self.face_offset) - 1


def _texture_table(textures, channels):
    offsets, data, pos = [0, 0, 0], [], 0  # entry 0: background
    stored: dict[int, list[int]] = {}      # objects sharing one array (glTF materials) share its texels
    for tex in textures:
        if tex is None:
            offsets += [0, 0, 0]
            continue
        if id(tex) in stored:
            offsets += stored[id(tex)]
            continue
        t = np.asarray(tex, np.float32)
        t = t.reshape(t.shape[0], t.shape[1], -1)[..., :channels]
        if t.shape[-1] < channels:         # a grey (H, W) texture is every channel's value
            t = np.repeat(t[..., :1], channels, axis=-1)
        stored[id(tex)] = [pos, t.shape[1], t.shape[0]]
        offsets += stored[id(tex)]
        data.append(t.ravel())
        pos += t.size // channels
    flat = np.concatenate(data) if data else np.zeros(channels, np.float32)
    return mi.UInt32(np.array(offsets, np.uint32)), mi.Float(flat)


def mitsuba_mesh(name, verts, faces, uvs, normals, obj_id, props=None):
    m = mi.Mesh(name, len(verts), len(faces), props=props or mi.Properties(),
                has_vertex_normals=normals is not None, has_vertex_texcoords=uvs is not None)
    p = mi.traverse(m)
    p["vertex_positions"] = mi.Float(verts.ravel())
    p["faces"] = mi.UInt32(faces.astype(np.uint32).ravel())
    if uvs is not None:
        p["vertex_texcoords"] = mi.Float(uvs.astype(np.float32).ravel())
    if normals is not None:
        p["vertex_normals"] = mi.Float(normals.astype(np.float32).ravel())
    p.update()
    m.add_attribute("face_objid", 1, [float(obj_id)] * len(faces))
    return m


def frame_geometry(scene: ResolvedScene, t: int) -> FrameGeometry:
    pos, nrm, uv, fcs, offsets = [], [], [], [], [0]
    shapes = {"type": "scene"}
    vbase = 0
    for i, mesh in enumerate(scene.meshes):
        v = scene.world_vertices(i, t).astype(np.float32)
        n = scene.world_normals(i, t)
        pos.append(v)
        nrm.append(np.zeros_like(v) if n is None else n.astype(np.float32))
        uv.append(np.zeros((len(v), 2), np.float32) if mesh.uvs is None else mesh.uvs.astype(np.float32))
        fcs.append(mesh.faces + vbase)
        vbase += len(v)
        offsets.append(offsets[-1] + len(mesh.faces))
        shapes[f"obj_{i}"] = mitsuba_mesh(f"obj_{i}", v, mesh.faces, mesh.uvs, n, i + 1)

    objs = scene.desc.objects
    albedo = np.array([[0, 0, 0]] + [o.material.albedo for o in objs], np.float32)
    emission = np.array([[0, 0, 0]] + [o.material.emission for o in objs], np.float32)
    smooth = [False] + [m.normals is not None for m in scene.meshes]
    obj_tex, tex_data = _texture_table(scene.textures, 3)
    obj_alpha, alpha_data = _texture_table(scene.alphas, 1)
    thr = np.array([1.0] + [o.material.alpha_threshold for o in objs], np.float32)
    return FrameGeometry(
        scene=scene, frame=t,
        positions=mi.Float(np.concatenate(pos).ravel()), vnormals=mi.Float(np.concatenate(nrm).ravel()),
        uvs=mi.Float(np.concatenate(uv).ravel()), faces=mi.UInt32(np.concatenate(fcs).astype(np.uint32).ravel()),
        face_offset=np.array(offsets, np.int64), obj_smooth=mi.Bool(smooth), obj_albedo=mi.Float(albedo.ravel()),
        obj_emission=mi.Float(emission.ravel()), has_emission=bool(emission.any()),
        obj_tex=obj_tex, tex_data=tex_data, obj_alpha=obj_alpha, obj_alpha_threshold=mi.Float(thr),
        alpha_data=alpha_data, has_alpha=any(a is not None for a in scene.alphas),
        mitsuba=mi.load_dict(shapes))
