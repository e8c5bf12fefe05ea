"""Raster frames: pyrender rasterises one sample per pixel, Dr.Jit rebuilds and shades each sample."""
import os

# Headless OpenGL through EGL (Mesa's llvmpipe here); must be chosen before OpenGL is imported.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from .frames import BUFFERS, Rasterizer  # noqa: E402

__all__ = ["BUFFERS", "Rasterizer"]
