"""Raster frames: pyrender rasterises one sample per pixel, Dr.Jit rebuilds and shades each sample."""
import os

# Headless OpenGL through EGL (Mesa's llvmpipe here); must be chosen before OpenGL is imported.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
# pyrender imports pyglet's window class: pyglet's X11 backend fails at import where no X client
# library is installed (a GPU server, measured); its headless one (EGL) does not.
os.environ.setdefault("PYGLET_HEADLESS", "1")

from .frames import BUFFERS, Rasterizer  # noqa: E402

__all__ = ["BUFFERS", "Rasterizer"]
