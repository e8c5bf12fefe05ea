"""Materials beyond Lambert: the glTF 2.0 metallic-roughness model (shading/brdf.py) with its
metallic-roughness, normal, emissive and occlusion textures (docs/method.md, "Shading model").

Normal maps are in tangent space. The tangent frame is generated per triangle from its UV
derivatives (shading/frame.py, face_tangents): T = dP/du made orthogonal to the interpolated
shading normal N (Gram-Schmidt), B = w N x T with w the sign of the triangle's UV orientation, and
the normal is n = normalize(T x + B y + N z) for the texel's (2 c - 1) (x, y scaled by the
material's normal_scale). A mesh that brings its own tangents (glTF TANGENT) uses them instead,
interpolated over the triangle. Towards a back face the frame turns with the normal, as the Khronos
sample viewer does.
Occlusion scales the ambient term only; lights are not occluded by it."""
from __future__ import annotations

import math
from typing import Callable

from backend import dr, mi

from .brdf import ambient_response, gltf_brdf
from .frame import FrameGeometry, SurfaceMaps
from .texels import lookup


def emission_scale(maps: SurfaceMaps, surf, hit, mips=None) -> mi.Color3f:
    """The emissive texture's value (1 where an object has none); `mips`: its filtered textures."""
    has, (r, g, b) = lookup(maps.emit_tex, maps.emit_data, mips, surf.obj, surf.uv, 3, hit, surf.foot)
    return dr.select(has, mi.Color3f(r, g, b), mi.Color3f(1.0))


def _vertex_tangent(geo: FrameGeometry, maps: SurfaceMaps, face, p, active):
    """The mesh's own tangent at p: its vertices' tangents interpolated with p's barycentric
    coordinates in the triangle (recomputed from p, so the raster and the reference agree), and
    the handedness of the triangle's first vertex."""
    idx = [dr.gather(mi.UInt32, geo.faces, face * 3 + k, active) for k in range(3)]
    v0, v1, v2 = (dr.gather(mi.Vector3f, geo.positions, i, active) for i in idx)
    e1, e2, ep = v1 - v0, v2 - v0, p - v0
    d00, d01, d11 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
    d20, d21 = dr.dot(ep, e1), dr.dot(ep, e2)
    inv = dr.rcp(d00 * d11 - d01 * d01)
    b1 = (d11 * d20 - d01 * d21) * inv
    b2 = (d00 * d21 - d01 * d20) * inv
    tan = [[dr.gather(mi.Float, maps.vtangents, i * 4 + k, active) for k in range(4)] for i in idx]
    t = sum((mi.Vector3f(*tv[:3]) * b for tv, b in zip(tan, (1.0 - b1 - b2, b1, b2))), mi.Vector3f(0.0))
    return t, tan[0][3]


def mapped_normal(geo: FrameGeometry, maps: SurfaceMaps, surf, n: mi.Vector3f, flip, hit) -> mi.Vector3f:
    """The shading normal n (already facing the viewer) bent by the object's normal map."""
    has, (x, y, z) = lookup(maps.normal_tex, maps.normal_data, geo.mips.get("normal_map"), surf.obj, surf.uv, 3,
                            hit, surf.foot)
    scale = dr.gather(mi.Float, maps.normal_scale, surf.obj, has)
    face = dr.gather(mi.UInt32, maps.face_base, surf.obj, has) + surf.prim
    tw = [dr.gather(mi.Float, maps.tangents, face * 4 + k, has) for k in range(4)]
    t, w = mi.Vector3f(tw[0], tw[1], tw[2]), tw[3]
    if maps.has_vtan:
        own = dr.gather(mi.Bool, maps.obj_vtan, surf.obj, has)
        t_v, w_v = _vertex_tangent(geo, maps, face, surf.p, own)
        t, w = dr.select(own, t_v, t), dr.select(own, w_v, w)
    t = dr.select(flip, -t, t)
    t = t - n * dr.dot(n, t)
    # a tangent along the normal (a degenerate asset tangent, a UV gradient across the normal) has no
    # direction left: any perpendicular one keeps the result finite
    t = dr.select(dr.squared_norm(t) > 1e-12, dr.normalize(t), mi.coordinate_system(n)[0])
    b = dr.cross(n, t) * dr.select(flip, -w, w)
    bent = t * ((2.0 * x - 1.0) * scale) + b * ((2.0 * y - 1.0) * scale) + n * (2.0 * z - 1.0)
    return dr.select(has & (dr.squared_norm(bent) > 0), dr.normalize(bent), n)


def shade_maps(geo: FrameGeometry, surf, view: mi.Vector3f, hit, base: mi.Color3f, n_sh: mi.Vector3f, flip,
               ambient: mi.Color3f, lights: Callable) -> tuple[mi.Color3f, mi.UInt32]:
    """Reflected radiance of a scene whose materials need maps or the metallic-roughness model.

    `view` is p - eye; `lights(n)` yields each light's (bit, l, E, max(0, n.l), reaches) for the
    normal n. Lights carry irradiance E with a Lambert surface's radiance albedo E cos (the
    project's convention: E is pi times a radiometric irradiance), so a BRDF f gives pi f E cos.
    Objects without the model (plain Lambert) give base (ambient occlusion + sum E cos) here."""
    maps = geo.maps
    obj = surf.obj
    model = dr.gather(mi.Bool, maps.gltf_model, obj, hit)
    metallic = dr.gather(mi.Float, maps.metallic, obj, hit)
    rough = dr.gather(mi.Float, maps.roughness, obj, hit)
    if maps.has_mr:
        has, (_, g, b) = lookup(maps.mr_tex, maps.mr_data, geo.mips.get("metallic_roughness"), obj, surf.uv, 3,
                                hit, surf.foot)
        rough = dr.select(has, rough * g, rough)
        metallic = dr.select(has, metallic * b, metallic)
    n = mapped_normal(geo, maps, surf, n_sh, flip, hit) if maps.has_normal else n_sh
    v = dr.normalize(-view)
    occ = mi.Float(1.0)
    if maps.has_occlusion:
        has, (o,) = lookup(maps.occ_tex, maps.occ_data, geo.mips.get("occlusion"), obj, surf.uv, 1, hit, surf.foot)
        strength = dr.gather(mi.Float, maps.occ_strength, obj, has)
        occ = dr.select(has, 1.0 + strength * (o - 1.0), 1.0)
    amb = ambient * occ * dr.select(model, ambient_response(dr.dot(n, v), base, metallic, rough), base)
    direct = mi.Color3f(0.0)
    mask = mi.UInt32(0)
    for bit, l_dir, e, cos, lit in lights(n):
        f = dr.select(model, math.pi * gltf_brdf(n, v, l_dir, base, metallic, rough), base)
        direct += dr.select(lit, f * e * cos, 0.0)
        mask |= dr.select(lit, mi.UInt32(bit), 0)
    return amb + direct, mask
