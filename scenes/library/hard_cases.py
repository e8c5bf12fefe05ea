"""Hard cases for temporal anti-aliasing, each isolating one known failure mode.

subpixel_lines  geometry thinner than a pixel (0.1 to 1.5 px at the quick resolution)
moire           a high-frequency checker texture on a plane at a grazing angle
hdr_contrast    an emitter of radiance 1e3 seen through thin dark bars (~1e-2)
fast_object     a small sphere crossing the whole screen in 12 frames
disocclusion    an occluder sliding off a textured background over 30 frames
camera_cut      24 frames with a hard camera cut at frame 12 (history must be reset)
"""
from __future__ import annotations

import numpy as np

from ..description import (Camera, CameraCut, DirectionalLight, Material, MeshSpec, Motion, Scene,
                           SceneObject, Texture, Transform)
from . import geometry as g
from .common import QUICK, SKY, SUN, WALL, _solid_box

# -- sub-pixel lines -----------------------------------------------------------------------------
LINE_WIDTHS_PX = (0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5)   # at the quick resolution's height (180)
LINE_ANGLES_DEG = (3.0, 20.0, 40.0, 60.0, 80.0, 89.0)    # short segments, from horizontal
_LINES_CAM = dict(position=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), yfov_deg=30.0)


def _pixel_size(distance: float, yfov_deg: float, height: int) -> float:
    """World size of one pixel on a fronto-parallel plane at `distance`."""
    return 2 * distance * np.tan(np.radians(yfov_deg) / 2) / height


def _line_quad(a, b, width) -> np.ndarray:
    """Four corners of a thin quad from a to b (in z = 0): v0 -> v3 spans the width."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([-t[1], t[0]]) * width / 2
    return np.array([[*(a - n), 0], [*(b - n), 0], [*(b + n), 0], [*(a + n), 0]])


def subpixel_lines_mesh(px: float) -> g.MeshData:
    """Seven rows, one per width in LINE_WIDTHS_PX: a long line tilted 1 degree across the image
    and twelve short segments at angles from 3 to 89 degrees. `px` is the pixel size in world units."""
    quads = []
    rows = len(LINE_WIDTHS_PX)
    pitch = 2.0 / rows
    for i, wpx in enumerate(LINE_WIDTHS_PX):
        w = wpx * px
        yc = 1.0 - (i + 0.5) * pitch
        half, rise = 1.8, 1.8 * np.tan(np.radians(1.0))
        quads.append(_line_quad((-half, yc + 0.1 - rise), (half, yc + 0.1 + rise), w))
        for j, x in enumerate(np.linspace(-1.65, 1.65, 12)):
            ang = np.radians(LINE_ANGLES_DEG[j % len(LINE_ANGLES_DEG)])
            d = 0.07 * np.array([np.cos(ang), np.sin(ang)])
            c = np.array([x, yc - 0.045])
            quads.append(_line_quad(c - d, c + d, w))
    v = np.concatenate(quads)
    k = np.arange(len(quads))[:, None] * 4
    f = np.concatenate([k + [0, 1, 2], k + [0, 2, 3]])
    return g.MeshData(v, f)


def subpixel_lines() -> Scene:
    px = _pixel_size(4.0, _LINES_CAM["yfov_deg"], QUICK.quick[1])
    return Scene(
        name="subpixel_lines", resolution=QUICK, transport="unlit",
        description="Light lines on a dark backdrop, seven rows of widths 0.1, 0.2, 0.35, 0.5, 0.75, 1 and "
                    "1.5 px (at 320x180), each a long 1-degree line and short segments at 3-89 degrees",
        stresses="geometry thinner than a pixel: lines that a single sample per pixel breaks into dashes "
                 "and that flicker under jitter; coverage far below the history's clamp box",
        camera=Camera(**_LINES_CAM, near=0.5, far=20),
        objects=(SceneObject(name="lines", mesh=g.spec(subpixel_lines_mesh(px)),
                             material=Material(albedo=(0.95, 0.93, 0.88))),
                 SceneObject(name="backdrop", mesh=g.spec(g.rect(-4, 4, -3, 3, -1.0)),
                             material=Material(albedo=(0.05, 0.06, 0.08)))),
        background=SKY)


# -- moire ----------------------------------------------------------------------------------------
MOIRE_SQUARE = 0.1            # world size of one checker square


def _checker(nu: int, nv: int, a=(0.85, 0.85, 0.8), b=(0.06, 0.06, 0.08)) -> np.ndarray:
    i, j = np.meshgrid(np.arange(nu), np.arange(nv))
    return np.where(((i + j) % 2 == 0)[..., None], a, b).astype(np.float32)


def moire() -> Scene:
    sx, sz = 8.0, 9.0
    nu, nv = int(round(sx / MOIRE_SQUARE)), int(round(sz / MOIRE_SQUARE))
    # a rect in x-y with UVs over [0,1]^2, laid flat (facing up) from z = 2.5 to z = -6.5; the
    # texture holds every square (one texel each) so UVs stay in [0, 1] where float32 is finest
    floor = g.moved(g.rect(-sx / 2, sx / 2, -2.5, sz - 2.5), axis=(1, 0, 0), deg=-90)
    return Scene(
        name="moire", resolution=QUICK, transport="direct",
        description=f"A black-and-white checker floor ({MOIRE_SQUARE:g}-unit squares, {nu}x{nv} texels) seen "
                    "from 0.4 units above it, out to 9 units away, in front of a plain wall",
        stresses="texture frequency rising through the pixel rate at a grazing angle: moire bands, and "
                 "squares that shrink below a pixel vertically while still wider than one horizontally",
        camera=Camera(position=(0.0, 0.4, 2.8), target=(0.0, -0.1, 0.0), yfov_deg=40, near=0.1, far=40),
        objects=(SceneObject(name="floor", mesh=g.spec(floor),
                             material=Material(albedo=(1.0, 1.0, 1.0),
                                               texture=Texture(kind="array", data=_checker(nu, nv)))),
                 SceneObject(name="far_wall", mesh=g.spec(g.rect(-6.0, 6.0, -0.1, 2.9, -6.6)),
                             material=Material(albedo=(0.35, 0.4, 0.5)))),
        lights=(DirectionalLight(direction=(0.3, -1.0, -0.4), intensity=(1.0, 1.0, 0.95)),),
        ambient=(0.25, 0.25, 0.27), background=SKY)


# -- HDR contrast ---------------------------------------------------------------------------------
HDR_EMISSION = (1000.0, 950.0, 880.0)
DARK = (0.04, 0.04, 0.045)    # with the ambient term below: ~1e-2 radiance


def hdr_contrast() -> Scene:
    px = _pixel_size(3.0, 40.0, QUICK.quick[1])
    bars = [g.box((0.026, 3.4, 0.02), (float(x), 0.0, 0.0), (0, 0, 1), 3.0) for x in np.arange(-2.2, 2.3, 0.22)]
    bars.append(g.box((5.0, 0.03, 0.02), (0.0, 0.55, 0.0), (0, 0, 1), -1.0))
    # two thin wires (0.4 px wide) crossing the grille diagonally
    wires = [g.box((0.4 * px, 3.8, 0.004), (0.0, 0.0, 0.05), (0, 0, 1), a) for a in (-32.0, 51.0)]
    return Scene(
        name="hdr_contrast", resolution=QUICK, transport="direct",
        description="A lamp panel of radiance 1e3 filling the view behind a dark grille of 2-px bars "
                    "(radiance ~1e-2) and two 0.4-px wires",
        stresses="HDR edges, 1e3 next to 1e-2: a sample on the lamp outweighs hundreds on the bars, so "
                 "linear-space blending and history clamping flicker and ring; fireflies on the wires",
        camera=Camera(position=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), yfov_deg=40, near=0.1, far=20),
        objects=(SceneObject(name="lamp", mesh=g.spec(g.rect(-5, 5, -3, 3, -0.4)),
                             material=Material(albedo=(0.0, 0.0, 0.0), emission=HDR_EMISSION)),
                 SceneObject(name="grille", mesh=g.spec(g.merge(*bars)), material=Material(albedo=DARK)),
                 SceneObject(name="wires", mesh=g.spec(g.merge(*wires)), material=Material(albedo=DARK))),
        ambient=(0.25, 0.25, 0.25), background=(0.0, 0.0, 0.0))


# -- fast object ----------------------------------------------------------------------------------
def _tiles(w: int = 16, h: int | None = None, seed: int = 3) -> np.ndarray:
    """(h, w, 3) muted random colours, one per texel: a tiled wall."""
    rng = np.random.default_rng(seed)
    return (0.25 + 0.5 * rng.random((h or w, w, 3))).astype(np.float32)


def fast_object() -> Scene:
    frames = 12
    x0, x1 = -5.2, 5.2
    return Scene(
        name="fast_object", resolution=QUICK, frames=frames, transport="direct",
        description="A small yellow sphere (radius 0.15) crossing the whole screen in 12 frames, in front "
                    "of a tiled wall; static camera",
        stresses="motion of about 3 object diameters (~35 px) a frame: the history under the object is "
                 "never valid, reprojection lands outside it, and ghost trails are long",
        camera=Camera(position=(0.0, 1.0, 6.0), target=(0.0, 0.9, 0.0), yfov_deg=45, near=0.1, far=40),
        objects=(SceneObject(name="tiles", mesh=g.spec(g.rect(-7, 7, -1.0, 4.0, -1.5)),
                             material=Material(texture=Texture(kind="array", data=_tiles(32, 12)), albedo=(1, 1, 1))),
                 SceneObject(name="floor", mesh=g.spec(g.moved(g.rect(-7, 7, -4.5, 1.5), axis=(1, 0, 0), deg=-90)),
                             material=Material(albedo=(0.5, 0.48, 0.45))),
                 SceneObject(name="ball", mesh=MeshSpec(kind="sphere", radius=0.15, segments=24, smooth=True),
                             material=Material(albedo=(0.9, 0.75, 0.1)),
                             transform=Transform(translate=(x0, 1.0, 0.5)),
                             motion=Motion(velocity=((x1 - x0) / (frames - 1), 0.0, 0.0),
                                           spin_axis=(0, 0, 1), spin_deg=-30.0))),
        lights=(SUN,), ambient=(0.2, 0.2, 0.22), background=SKY)


# -- disocclusion ---------------------------------------------------------------------------------
def disocclusion() -> Scene:
    frames = 30
    tiles = Texture(kind="array", data=_tiles(48, 24, seed=7))
    # The target is off the texel grid on purpose: aimed at a tile corner, a tile boundary would run
    # through pixel centres, where raster and reference may pick different texels by float rounding.
    return Scene(
        name="disocclusion", resolution=QUICK, frames=frames, transport="direct",
        description="A dark panel sliding right, off a wall of 48x24 coloured tiles, over 30 frames",
        stresses="newly revealed texture detail with no history behind the moving edge: the region "
                 "behind the panel must be rebuilt from scratch (blur / ghosting of the panel)",
        camera=Camera(position=(0.2, 0.2, 3.2), target=(0.031, 0.017, 0.0), yfov_deg=40, near=0.1, far=30),
        objects=(SceneObject(name="tiles", mesh=MeshSpec(kind="plane", size=(4.0, 2.0, 0)),
                             material=Material(albedo=(1, 1, 1), texture=tiles)),
                 *g.surface_objects("panel", g.box((1.6, 1.5, 0.1)), Material(albedo=(0.12, 0.14, 0.2)),
                                    Transform(translate=(-0.9, 0.0, 0.6)), Motion(velocity=(0.11, 0.0, 0.0))),
                 *_solid_box("post", (0.08, 2.6, 0.08), (1.3, 0.0, 0.3), (0.6, 0.3, 0.1))),
        lights=(DirectionalLight(direction=(0.2, -0.3, -1.0), intensity=(0.9, 0.9, 0.9)),),
        ambient=(0.15, 0.15, 0.15), background=SKY)


# -- camera cut -----------------------------------------------------------------------------------
def camera_cut() -> Scene:
    frames, cut = 24, 12
    objs = [*_solid_box("floor", (10.0, 0.1, 10.0), (0.0, -0.05, 0.0), (0.5, 0.5, 0.48)),
            *_solid_box("back_wall", (10.0, 3.0, 0.1), (0.0, 1.5, -3.0), (0.45, 0.5, 0.6)),
            SceneObject(name="tiles", mesh=g.spec(g.rect(-1.0, 1.0, 0.0, 2.0, 0.0)),
                        material=Material(texture=Texture(kind="array", data=_tiles(12, seed=9)), albedo=(1, 1, 1)),
                        transform=Transform(translate=(-2.5, 0.2, -2.9)))]
    for i, x in enumerate(np.linspace(-3, 3, 7)):
        objs += _solid_box(f"pillar_{i}", (0.15, 2.5, 0.15), (float(x), 1.25, -1.2), WALL)
    objs += _solid_box("crate", (0.8, 0.8, 0.8), (1.5, 0.4, 0.6), (0.55, 0.35, 0.15), rotate_deg=30.0)
    objs.append(SceneObject(name="ball", mesh=MeshSpec(kind="sphere", radius=0.45, segments=32, smooth=True),
                            material=Material(albedo=(0.2, 0.5, 0.8)),
                            transform=Transform(translate=(-0.8, 0.45, 0.8))))
    return Scene(
        name="camera_cut", resolution=QUICK, frames=frames, transport="direct_shadows",
        description=f"{frames} frames: a slow pan across a hall of pillars, then at frame {cut} a hard cut to a "
                    "low view from the side, which goes on moving sideways",
        stresses="history that is wrong everywhere after a cut: TAA must reset (or reject everything) "
                 "instead of blending two unrelated images",
        camera=Camera(position=(-1.0, 1.5, 5.0), target=(-0.5, 0.9, 0.0), yfov_deg=50, near=0.1, far=40,
                      velocity=(0.06, 0.0, 0.0), target_velocity=(0.06, 0.0, 0.0),
                      cuts=(CameraCut(frame=cut, position=(4.2, 0.7, 2.6), target=(0.0, 0.8, -0.5)),)),
        objects=tuple(objs), lights=(SUN,), ambient=(0.2, 0.21, 0.24), background=SKY)
