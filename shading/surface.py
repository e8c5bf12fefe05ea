"""Surface shading in Dr.Jit, called per pixel by the raster and per sample by the reference.

Light transport (declared by the scene, nothing more is computed):
  unlit           colour = albedo
  direct          colour = albedo * (ambient + sum_i E_i * max(0, n . l_i))
  direct_shadows  as direct, each light term times a visibility ray against the same triangles
A material's emission is added to the result in every mode. A scene that declares 'path' gets
Mitsuba's multi-bounce path tracer as its reference (references/mitsuba_scene.py); its raster
frames are shaded as direct_shadows, and the gap between the two is reported, not hidden.
Directional lights give E = intensity; point lights E = intensity / d^2. Surfaces are two-sided:
normals are turned to face the viewer. Textures use nearest-texel lookup with wrap-around, or
the filter they declare (shading/texels.py, docs/method.md "Texture filtering").
Materials beyond Lambert (the glTF metallic-roughness model, normal, occlusion and emissive maps)
are shaded by shading/material.py, traced only in scenes that have them, so a Lambert scene's
kernel is the one above.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from backend import dr, mi, opaque
from scenes.description import DirectionalLight

from . import material
from .frame import FrameGeometry
from .texels import lookup as _lookup
from .texels import texel as _texel

MAX_ALPHA_LAYERS = 8   # cut-out surfaces skipped along one ray before giving up (counted as a miss)


@dataclass
class Surface:
    obj: mi.UInt32         # object id, 0 = background
    p: mi.Point3f
    n_geo: mi.Vector3f     # unit geometric normal
    n_sh: mi.Vector3f      # unit shading normal (interpolated for smooth objects)
    uv: mi.Point2f
    prim: mi.UInt32 | None = None   # triangle index within the object, where known
    # the raster's ((du/dx, dv/dx, du/dy, dv/dy), lod_bias) for trilinear textures; None: the base
    # level (the reference, which integrates over the pixel by sampling it)
    foot: tuple | None = None


def albedo_at(geo: FrameGeometry, obj, uv, active=True, foot=None) -> mi.Color3f:
    """Albedo times the object's texture, looked up with its filter (`foot`: Surface.foot)."""
    base = dr.gather(mi.Color3f, geo.obj_albedo, obj, active)
    has, (r, g, b) = _lookup(geo.obj_tex, geo.tex_data, geo.mips.get("texture"), obj, uv, 3, active, foot)
    return dr.select(has, base * mi.Color3f(r, g, b), base)


def alpha_keeps(geo: FrameGeometry, obj, uv, active=True) -> mi.Bool:
    """True where the surface is opaque (no cut-out texture, or alpha >= its threshold)."""
    has, (a,) = _texel(geo.obj_alpha, geo.alpha_data, obj, uv, 1, active)
    thr = dr.gather(mi.Float, geo.obj_alpha_threshold, obj, active)
    return ~has | (a >= thr)


def _object_id(si) -> mi.UInt32:
    return dr.select(si.is_valid(), mi.UInt32(si.shape.eval_attribute_1("face_objid", si)), 0)


def _intersect_opaque(geo: FrameGeometry, ray: mi.Ray3f, active):
    """Closest intersection that survives the alpha test (cut-out texels are passed through)."""
    si = geo.mitsuba.ray_intersect(ray, active)
    if not geo.has_alpha:
        return si
    for _ in range(MAX_ALPHA_LAYERS):
        cut = si.is_valid() & ~alpha_keeps(geo, _object_id(si), si.uv, si.is_valid())
        if not dr.any(cut):
            return si
        nxt = si.spawn_ray(ray.d)
        nxt.maxt = dr.maximum(ray.maxt - si.t, 0.0)
        si_next = geo.mitsuba.ray_intersect(nxt, cut)
        si_next.t += si.t
        si = dr.select(cut, si_next, si)
    still = si.is_valid() & ~alpha_keeps(geo, _object_id(si), si.uv, si.is_valid())
    si.t = dr.select(still, dr.inf, si.t)   # too many layers: treated as a miss
    return si


def trace_visible(geo: FrameGeometry, ray: mi.Ray3f, active=True) -> tuple[Surface, mi.Float]:
    """The surface a camera ray sees (Mitsuba's BVH), as a Surface, and the hit distance."""
    si = _intersect_opaque(geo, ray, active)
    valid = si.is_valid()
    surf = Surface(obj=dr.select(valid, _object_id(si), 0), p=si.p, n_geo=mi.Vector3f(si.n),
                   n_sh=mi.Vector3f(si.sh_frame.n), uv=si.uv, prim=si.prim_index)
    return surf, si.t


def _occluded(geo: FrameGeometry, origin, direction, dist, active) -> mi.Bool:
    ray = mi.Ray3f(origin, direction)
    ray.maxt = dist
    if not geo.has_alpha:
        return geo.mitsuba.ray_test(ray, active)
    return _intersect_opaque(geo, ray, active).is_valid()


def _lights(geo: FrameGeometry, p, origin, n, hit):
    """Per light, in order: (its light-mask bit, unit direction to it, irradiance E at p,
    max(0, n . l), whether it reaches p: facing n and, with shadows, unoccluded)."""
    desc = geo.scene.desc
    shadows = desc.transport in ("direct_shadows", "path")
    for light in desc.lights:
        if isinstance(light, DirectionalLight):
            d = -np.asarray(light.direction, float)
            l_dir = opaque(mi.Vector3f, *(d / np.linalg.norm(d)))
            dist, e = mi.Float(dr.inf), opaque(mi.Color3f, *light.intensity)
        else:
            to_light = opaque(mi.Point3f, *light.position) - p
            dist = dr.norm(to_light)
            l_dir = to_light / dist
            e = opaque(mi.Color3f, *light.intensity) / dr.square(dist)
        cos = dr.maximum(dr.dot(n, l_dir), 0.0)
        lit = hit & (cos > 0)
        if shadows:
            lit &= ~_occluded(geo, origin, l_dir, dist * (1 - 1e-4), lit)
        yield 1 << desc.lights.index(light), l_dir, e, cos, lit


def shade(geo: FrameGeometry, surf: Surface, eye: np.ndarray, active=True,
          light_mask: list | None = None) -> mi.Color3f:
    """Outgoing radiance towards the camera at `eye` (world position).

    If `light_mask` is a list, a UInt32 is appended to it: bit i set where light i reaches the
    point (facing and unoccluded); shadow boundaries are where it changes."""
    mask = mi.UInt32(0)
    desc = geo.scene.desc
    hit = mi.Bool(active) & (surf.obj > 0)
    albedo = albedo_at(geo, surf.obj, surf.uv, hit, surf.foot)
    if desc.transport == "unlit":
        colour = albedo
    else:
        view = surf.p - opaque(mi.Point3f, *eye)
        flip = dr.dot(surf.n_geo, view) > 0
        n_geo = dr.select(flip, -surf.n_geo, surf.n_geo)
        n_sh = dr.select(flip, -surf.n_sh, surf.n_sh)
        irradiance = opaque(mi.Color3f, *desc.ambient)
        origin = surf.p + n_geo * (1e-4 * (1.0 + dr.max(dr.abs(surf.p))))
        if geo.maps is None:     # Lambert only: the kernel every such scene always had
            for bit, _, e, cos, lit in _lights(geo, surf.p, origin, n_sh, hit):
                irradiance += dr.select(lit, e * cos, 0.0)
                mask |= dr.select(lit, mi.UInt32(bit), 0)
            colour = albedo * irradiance
        else:
            colour, mask = material.shade_maps(geo, surf, view, hit, albedo, n_sh, flip, irradiance,
                                               lambda n: _lights(geo, surf.p, origin, n, hit))
    if geo.has_emission:
        emission = dr.gather(mi.Color3f, geo.obj_emission, surf.obj, hit)
        if geo.maps is not None and geo.maps.has_emit_tex:
            emission *= material.emission_scale(geo.maps, surf, hit, geo.mips.get("emission_texture"))
        colour += emission
    if light_mask is not None:
        light_mask.append(dr.select(hit, mask, 0))
    return dr.select(hit, colour, opaque(mi.Color3f, *desc.background))
