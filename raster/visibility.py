"""The visibility pass: pyrender's EGL context, primitives and shader cache, with our own
single-sample framebuffer.

pyrender always draws colour into a 4x multisampled renderbuffer and returns it 8-bit and
gamma-encoded (pow 1/2.2, clamped), which would anti-alias the very input TAA must start from. So we
rasterise only integer IDs into a single-sample RG32UI target (there is no multisample buffer at
all) and rebuild every float buffer per pixel from the triangle that the pixel's one sample hit:
a visibility buffer. The sample sits at the centre of the jittered projection's pixel.
"""
from __future__ import annotations

import os

import numpy as np

from scenes import ResolvedScene

# pyrender and OpenGL, imported with the first context: pyrender's import (trimesh, scipy.spatial,
# networkx, pyglet) took 0.8-1.6 s, which a study or report with nothing to rasterise need not pay.
gl = pyrender = GLTF = egl = ShaderProgramCache = None


def _import_gl() -> None:
    global gl, pyrender, GLTF, egl, ShaderProgramCache
    if gl is not None:
        return
    import pyrender as _pyrender
    from OpenGL import GL as _gl
    from OpenGL import images as gl_images
    from pyrender.constants import GLTF as _GLTF
    from pyrender.platforms import egl as _egl
    from pyrender.shader_program import ShaderProgramCache as _Cache
    # PyOpenGL 3.1.0 (pinned by pyrender) does not know the integer formats' component counts.
    gl_images.COMPONENT_COUNTS.setdefault(_gl.GL_RG_INTEGER, 2)
    pyrender, GLTF, egl, ShaderProgramCache, gl = _pyrender, _GLTF, _egl, _Cache, _gl

SHADER_DIR = os.path.join(os.path.dirname(__file__), "shaders")
__code_files__ = ("shaders/*",)   # part of this module's code identity (provenance)


class RasterError(RuntimeError):
    pass


_PLATFORM = None


def _shared_platform():
    """One surfaceless EGL context per process: pyrender's delete_context terminates the EGL
    display, which would invalidate every other context, so ours is never deleted."""
    global _PLATFORM
    _import_gl()
    if _PLATFORM is None:
        try:
            device = egl.get_device_by_index(int(os.environ.get("EGL_DEVICE_ID", "0")))
            platform = egl.EGLPlatform(16, 16, device=device)
            platform.init_context()
        except Exception as exc:
            raise RasterError(f"cannot create a headless OpenGL (EGL) context: {exc}. "
                              "Install Mesa's EGL driver: apt-get install libegl1 libegl-mesa0 "
                              "libgl1-mesa-dri") from exc
        _PLATFORM = platform
    _PLATFORM.make_current()
    return _PLATFORM


_GL_LIMITS: tuple[int, int, int] | None = None


def gl_limits() -> tuple[int, int, int]:
    """(GL_MAX_RENDERBUFFER_SIZE, GL_MAX_VIEWPORT_DIMS width, height) of this process's context,
    queried once."""
    global _GL_LIMITS
    if _GL_LIMITS is None:
        _shared_platform()
        rb = int(gl.glGetIntegerv(gl.GL_MAX_RENDERBUFFER_SIZE))
        vw, vh = (int(v) for v in np.asarray(gl.glGetIntegerv(gl.GL_MAX_VIEWPORT_DIMS)).ravel()[:2])
        _GL_LIMITS = (rb, vw, vh)
    return _GL_LIMITS


class VisibilityPass:
    def __init__(self, width: int, height: int):
        from .limits import check_size
        check_size(width, height, "the visibility pass")     # the package's own limit (raster.limits)
        self.width, self.height = width, height
        self._platform = _shared_platform()
        rb, vw, vh = gl_limits()
        if max(width, height) > rb or width > vw or height > vh:
            raise RasterError(f"{width}x{height} is beyond this OpenGL context's limits "
                              f"(GL_MAX_RENDERBUFFER_SIZE {rb}, GL_MAX_VIEWPORT_DIMS {vw}x{vh})")
        self._programs = ShaderProgramCache(SHADER_DIR)
        self._fb = gl.glGenFramebuffers(1)
        self._cb, self._db = gl.glGenRenderbuffers(2)
        gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, self._cb)
        gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_RG32UI, width, height)
        gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, self._db)
        gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_DEPTH_COMPONENT32F, width, height)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self._fb)
        gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_RENDERBUFFER, self._cb)
        gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_RENDERBUFFER, self._db)
        status = gl.glCheckFramebufferStatus(gl.GL_FRAMEBUFFER)
        if status != gl.GL_FRAMEBUFFER_COMPLETE:
            raise RasterError(f"visibility framebuffer incomplete (status {status:#x})")
        samples = gl.glGetIntegerv(gl.GL_SAMPLES)
        self.samples_per_pixel = max(int(samples), 1)
        self._prims: dict[int, tuple[tuple, pyrender.Primitive, int | None]] = {}

    # -- per-object GPU data ------------------------------------------------------------------
    def _alpha_texture(self, alpha: np.ndarray) -> int:
        tex = gl.glGenTextures(1)
        gl.glBindTexture(gl.GL_TEXTURE_2D, tex)
        gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)
        gl.glTexImage2D(gl.GL_TEXTURE_2D, 0, gl.GL_R32F, alpha.shape[1], alpha.shape[0], 0,
                        gl.GL_RED, gl.GL_FLOAT, np.ascontiguousarray(alpha, np.float32))
        for p in (gl.GL_TEXTURE_MIN_FILTER, gl.GL_TEXTURE_MAG_FILTER):
            gl.glTexParameteri(gl.GL_TEXTURE_2D, p, gl.GL_NEAREST)
        return tex

    def _primitive(self, scene: ResolvedScene, i: int, t: int) -> tuple[pyrender.Primitive, int | None]:
        key = (scene.content_hash, 0 if scene.is_static(i) else t)
        cached = self._prims.get(i)
        if cached is not None and cached[0] == key:
            return cached[1], cached[2]
        if cached is not None:
            cached[1]._remove_from_context()
            if cached[2] is not None:
                gl.glDeleteTextures([cached[2]])
        mesh, alpha = scene.meshes[i], scene.alphas[i]
        prim = pyrender.Primitive(positions=scene.world_vertices(i, t).astype(np.float32),
                                  indices=mesh.faces.astype(np.uint32),
                                  texcoord_0=None if alpha is None else mesh.uvs.astype(np.float32),
                                  mode=GLTF.TRIANGLES)
        prim._add_to_context()
        tex = None if alpha is None else self._alpha_texture(alpha)
        self._prims[i] = (key, prim, tex)
        return prim, tex

    # -- the pass ----------------------------------------------------------------------------
    def render(self, scene: ResolvedScene, t: int, view: np.ndarray, proj: np.ndarray):
        """(object id, triangle id) per pixel as two (H, W) uint32 arrays; object id 0 = nothing."""
        self._platform.make_current()
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self._fb)
        gl.glViewport(0, 0, self.width, self.height)
        gl.glDisable(gl.GL_MULTISAMPLE)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_CULL_FACE)            # every surface is two-sided, as in the reference
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glClearBufferuiv(gl.GL_COLOR, 0, np.zeros(4, np.uint32))
        gl.glClearBufferfv(gl.GL_DEPTH, 0, np.ones(1, np.float32))
        for i in range(len(scene.meshes)):
            prim, tex = self._primitive(scene, i, t)
            defines = {"INST_M_LOC": 2 if tex is not None else 1}
            if tex is not None:
                defines["TEXCOORD_0_LOC"] = 1
            prog = self._programs.get_program("vis.vert", "vis.frag", defines=defines)
            if not prog._in_context():
                prog._add_to_context()
            prog._bind()
            prog.set_uniform("V", view.astype(np.float32))
            prog.set_uniform("P", proj.astype(np.float32))
            gl.glUniform1ui(gl.glGetUniformLocation(prog._program_id, "object_id"), i + 1)
            if tex is not None:
                gl.glActiveTexture(gl.GL_TEXTURE0)
                gl.glBindTexture(gl.GL_TEXTURE_2D, tex)
                prog.set_uniform("alpha_tex", 0)
                a = scene.alphas[i]
                gl.glUniform2i(gl.glGetUniformLocation(prog._program_id, "alpha_size"), a.shape[1], a.shape[0])
                prog.set_uniform("alpha_threshold", float(scene.desc.objects[i].material.alpha_threshold))
            prim._bind()
            gl.glDrawElements(gl.GL_TRIANGLES, prim.indices.size, gl.GL_UNSIGNED_INT, None)
            prim._unbind()
            prog._unbind()
        gl.glFinish()
        buf = gl.glReadPixels(0, 0, self.width, self.height, gl.GL_RG_INTEGER, gl.GL_UNSIGNED_INT)
        ids = np.frombuffer(buf, np.uint32).reshape(self.height, self.width, 2)[::-1]
        return ids[..., 0].copy(), ids[..., 1].copy()

    def close(self):
        self._platform.make_current()
        for _, prim, tex in self._prims.values():
            prim._remove_from_context()
            if tex is not None:
                gl.glDeleteTextures([tex])
        self._prims.clear()
        gl.glDeleteFramebuffers(1, [self._fb])
        gl.glDeleteRenderbuffers(2, [self._cb, self._db])
        self._programs.clear()
