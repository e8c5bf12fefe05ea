"""Shading shared by the raster and the reference (docs/method.md): one Dr.Jit function per
surface point, so the two renderers differ only in where their samples fall."""
from .frame import FrameGeometry, frame_geometry
from .surface import Surface, shade, albedo_at, trace_visible

__all__ = ["FrameGeometry", "frame_geometry", "Surface", "shade", "albedo_at", "trace_visible"]
