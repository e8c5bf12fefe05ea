"""One frame's geometry in world space, as Dr.Jit tables and as a Mitsuba scene.

World-space vertices are computed once here in float64 and rounded to float32, so the raster's
surface reconstruction and Mitsuba's ray tracer intersect exactly the same triangles.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from backend import dr, mi
from scenes import ResolvedScene

from .mips import mip_table


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
    maps: "SurfaceMaps | None" = None   # only where a material goes beyond Lambert + emission
    # texture role (a Material field) -> shading.mips.MipTable, only for roles some object filters
    mips: dict = field(default_factory=dict)

    @property
    def n_objects(self) -> int:
        return len(self.face_offset) - 1


@dataclass
class SurfaceMaps:
    """Per-object parameters of the glTF metallic-roughness model and the material textures,
    present only in scenes that use them (a Lambert scene's kernels are the ones it always had).
    Texture tables are laid out as FrameGeometry.obj_tex (offset, width, height per object id)."""
    gltf_model: mi.Bool       # per object id: shaded by the metallic-roughness model
    metallic: mi.Float
    roughness: mi.Float
    mr_tex: mi.UInt32         # rgb; G scales roughness, B metallic
    mr_data: mi.Float
    has_mr: bool
    normal_tex: mi.UInt32     # rgb in [0, 1], decoded as 2 c - 1
    normal_data: mi.Float
    normal_scale: mi.Float
    has_normal: bool
    tangents: mi.Float        # per global face: world dP/du (xyz) and the sign of the uv frame
    face_base: mi.UInt32      # per object id: its first global face
    has_vtan: bool            # some normal-mapped mesh brings its own tangents (glTF TANGENT)
    obj_vtan: mi.Bool         # per object id: interpolate vtangents instead of the face's tangent
    vtangents: mi.Float       # per global vertex: world tangent xyz and w (zero where none)
    emit_tex: mi.UInt32
    emit_data: mi.Float
    has_emit_tex: bool
    occ_tex: mi.UInt32        # R scales the ambient term, by occlusion_strength
    occ_data: mi.Float
    occ_strength: mi.Float
    has_occlusion: bool


def face_tangents(verts: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None) -> np.ndarray:
    """(F, 4): each triangle's dP/du from its UV derivatives (the solution of
    e1 = du1 T + dv1 B, e2 = du2 T + dv2 B), and w = +1 where (T, B, face normal) is right-handed,
    -1 where the UV map is mirrored. Triangles without a UV gradient get an edge and w = +1."""
    t = verts[faces].astype(np.float64)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    if uvs is None:
        uvs = np.zeros((len(verts), 2))
    w = uvs[faces].astype(np.float64)
    d1, d2 = w[:, 1] - w[:, 0], w[:, 2] - w[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    tan = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
    bit = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    n = np.cross(e1, e2)
    sign = np.where(np.einsum("ij,ij->i", np.cross(tan, bit), n) < 0, -1.0, 1.0)
    bad = ~ok | (np.linalg.norm(tan, axis=1) == 0)
    tan[bad], sign[bad] = e1[bad], 1.0
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    return np.concatenate([tan, sign[:, None]], 1)


def _surface_maps(scene: ResolvedScene, t: int, face_offset: np.ndarray) -> SurfaceMaps | None:
    objs = scene.desc.objects
    if not any(o.material.is_gltf_model for o in objs) and not any(scene.maps):
        return None
    mats = [o.material for o in objs]
    per = lambda key: [m.get(key) for m in scene.maps]   # noqa: E731
    mr_tex, mr_data = _texture_table(per("metallic_roughness"), 3)
    n_tex, n_data = _texture_table(per("normal_map"), 3)
    e_tex, e_data = _texture_table(per("emission_texture"), 3)
    o_tex, o_data = _texture_table(per("occlusion"), 1)
    has_normal = any(m.normal_map is not None for m in mats)
    tangents = np.zeros((1, 4))
    if has_normal:
        tangents = np.concatenate([face_tangents(scene.world_vertices(i, t), mesh.faces, mesh.uvs)
                                   for i, mesh in enumerate(scene.meshes)])
    own = [m.normal_map is not None and mesh.tangents is not None for m, mesh in zip(mats, scene.meshes)]
    vtan = np.zeros((1, 4))
    if any(own):
        vtan = np.concatenate([scene.world_tangents(i, t) if own[i] else np.zeros((len(mesh.vertices), 4))
                               for i, mesh in enumerate(scene.meshes)])
    return SurfaceMaps(
        has_vtan=any(own), obj_vtan=mi.Bool([False] + own), vtangents=mi.Float(vtan.astype(np.float32).ravel()),
        gltf_model=mi.Bool([False] + [m.is_gltf_model for m in mats]),
        metallic=mi.Float([0.0] + [float(m.metallic or 0.0) for m in mats]),
        roughness=mi.Float([1.0] + [1.0 if m.roughness is None else float(m.roughness) for m in mats]),
        mr_tex=mr_tex, mr_data=mr_data, has_mr=any(m.metallic_roughness is not None for m in mats),
        normal_tex=n_tex, normal_data=n_data, normal_scale=mi.Float([1.0] + [float(m.normal_scale) for m in mats]),
        has_normal=has_normal, tangents=mi.Float(tangents.astype(np.float32).ravel()),
        face_base=mi.UInt32(np.concatenate([[0], face_offset[:-1]]).astype(np.uint32)),
        emit_tex=e_tex, emit_data=e_data, has_emit_tex=any(m.emission_texture is not None for m in mats),
        occ_tex=o_tex, occ_data=o_data, occ_strength=mi.Float([0.0] + [float(m.occlusion_strength) for m in mats]),
        has_occlusion=any(m.occlusion is not None for m in mats))


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
        mitsuba=mi.load_dict(shapes), maps=_surface_maps(scene, t, np.array(offsets)),
        mips=_mip_tables(scene))


def _mip_tables(scene: ResolvedScene) -> dict:
    """The filtered textures of each role (shading.mips), by Material field."""
    objs = scene.desc.objects
    out = {}
    for role, channels in (("texture", 3), ("metallic_roughness", 3), ("normal_map", 3),
                           ("emission_texture", 3), ("occlusion", 1)):
        arrays = scene.textures if role == "texture" else [m.get(role) for m in scene.maps]
        filters = [getattr(getattr(o.material, role), "filter", "nearest") for o in objs]
        biases = [getattr(getattr(o.material, role), "lod_bias", 0.0) for o in objs]
        table = mip_table(arrays, filters, channels, biases)
        if table is not None:
            out[role] = table
    return out
