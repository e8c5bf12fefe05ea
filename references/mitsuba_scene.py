"""Mitsuba objects matched to our camera: a perspective sensor with a box-filtered float32 film,
and an integrator that calls the shared shading function (spec section 4)."""
from __future__ import annotations

import numpy as np

from backend import dr, mi
from scenes.camera import CameraState
from shading import FrameGeometry, shade, trace_visible


def sensor(cam: CameraState, spp: int):
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
                 "rfilter": {"type": "box"}, "pixel_format": "rgb", "component_format": "float32"},
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
    return mi.load_dict({"type": "path", "max_depth": max_depth})
