"""Mitsuba objects matched to our camera: a perspective sensor with a box-filtered float32 film,
and an integrator that calls the shared shading function (shading/__init__.py)."""
from __future__ import annotations

import numpy as np

from backend import dr, mi
from scenes import ResolvedScene
from scenes.camera import CameraState
from scenes.description import DirectionalLight
from shading import FrameGeometry, shade, trace_visible
from shading.frame import mitsuba_mesh


def sensor(cam: CameraState, spp: int, alpha: bool = False):
    """Mitsuba's camera looks down +z with x to the left; look_at hides that, so we pass the
    same eye, target and up. The box filter makes each sample count for its own pixel only."""
    eye = cam.position
    fwd = -cam.to_world[:3, 2]
    up = cam.to_world[:3, 1]
    return mi.load_dict({
        "type": "perspective", "fov": cam.yfov_deg, "fov_axis": "y",
        "near_clip": cam.near, "far_clip": cam.far,
        "to_world": mi.ScalarTransform4f().look_at(origin=[float(c) for c in eye],
                                                   target=[float(c) for c in eye + fwd],
                                                   up=[float(c) for c in up]),
        "film": {"type": "hdrfilm", "width": cam.width, "height": cam.height,
                 "rfilter": {"type": "box"}, "pixel_format": "rgba" if alpha else "rgb", "component_format": "float32"},
        "sampler": {"type": "multijitter", "sample_count": spp},
    })


class SharedShadingIntegrator(mi.SamplingIntegrator):
    """Direct shading of the first opaque hit, via shading.shade (the raster's function)."""

    def __init__(self, geo: FrameGeometry, eye: np.ndarray):
        super().__init__(mi.Properties())
        self.geo, self.eye = geo, eye

    def sample(self, scene, sampler, ray, medium=None, active=True):
        surf, _ = trace_visible(self.geo, mi.Ray3f(ray), active)
        return mi.Spectrum(shade(self.geo, surf, self.eye, active)), mi.Bool(True), []

    def aov_names(self):
        return []

    def to_string(self):
        return "SharedShadingIntegrator[]"


def path_integrator(max_depth: int = 8):
    # Emitters hidden from camera rays: misses get alpha 0 and are composited over the scene's
    # background, as the raster does, while the ambient environment still lights the scene.
    return mi.load_dict({"type": "path", "max_depth": max_depth, "hide_emitters": True})


def _texture(data: np.ndarray, filt: str = "nearest"):
    # a bilinear or trilinear texture is its base level, bilinearly, as in every reference
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(data, np.float32)),
            "filter_type": "nearest" if filt == "nearest" else "bilinear", "wrap_mode": "repeat", "raw": True}


def path_scene(scene: ResolvedScene, t: int):
    """The same triangles with Mitsuba materials and emitters, for transport 'path'.

    Our direct model is L = albedo * (ambient + sum E cos); Mitsuba's diffuse BSDF is albedo / pi,
    so lights are scaled by pi and the ambient term becomes a constant environment of radiance
    `ambient`. Surfaces are two-sided like ours; cut-outs use Mitsuba's mask with a binary
    opacity; emission becomes an area emitter (one-sided in Mitsuba, unlike ours)."""
    desc = scene.desc
    d: dict = {"type": "scene"}
    for i, (obj, mesh) in enumerate(zip(desc.objects, scene.meshes)):
        mat = obj.material
        refl = {"type": "rgb", "value": list(mat.albedo)}
        if scene.textures[i] is not None:
            refl = _texture(scene.textures[i] * np.asarray(mat.albedo, np.float32), mat.texture.filter)
        bsdf = {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": refl}}
        if scene.alphas[i] is not None:
            keep = (scene.alphas[i] >= mat.alpha_threshold).astype(np.float32)
            bsdf = {"type": "mask", "opacity": _texture(keep[..., None]), "bsdf": bsdf}
        props = mi.Properties()
        props["bsdf"] = mi.load_dict(bsdf)
        if any(mat.emission):
            props["emitter"] = mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": list(mat.emission)}})
        n = scene.world_normals(i, t)
        d[f"obj_{i}"] = mitsuba_mesh(f"obj_{i}", scene.world_vertices(i, t).astype(np.float32), mesh.faces,
                                     mesh.uvs, n, i + 1, props)
    for k, light in enumerate(desc.lights):
        val = {"type": "rgb", "value": [float(np.pi * c) for c in light.intensity]}
        if isinstance(light, DirectionalLight):
            d[f"light_{k}"] = {"type": "directional", "direction": list(light.direction), "irradiance": val}
        else:
            d[f"light_{k}"] = {"type": "point", "position": list(light.position), "intensity": val}
    if any(desc.ambient):
        d["ambient"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(desc.ambient)}}
    return mi.load_dict(d)
