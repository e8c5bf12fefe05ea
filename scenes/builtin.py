"""Built-in scenes, rebuilt procedurally after the thesis's test scenes (spec section 10)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from .description import (Camera, DirectionalLight, Material, MeshSpec, Motion, PointLight,
                          Resolution, Scene, SceneObject, Texture, Transform)

QUICK = Resolution(quick=(320, 180), full=(1600, 900))
BROWN = (0.35, 0.16, 0.06)
BLUE = (0.1, 0.2, 0.6)
WALL = (0.7, 0.68, 0.62)
SUN = DirectionalLight(direction=(-0.4, -1.0, -0.6), intensity=(2.2, 2.1, 1.9))
SKY = (0.18, 0.2, 0.24)


def _box(name, size, at, albedo, **kw) -> SceneObject:
    return SceneObject(name=name, mesh=MeshSpec(kind="box", size=size), material=Material(albedo=albedo),
                       transform=Transform(translate=at, **kw))


def _text_texture() -> np.ndarray:
    """Black letters on white, drawn in code; nearest-neighbour lookup keeps the hard edges."""
    from PIL import Image, ImageDraw, ImageFont
    img = Image.new("L", (512, 256), 255)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=44)
    for row, line in enumerate(("TEMPORAL ANTI", "ALIASING: THE", "HISTORY IS A LIE")):
        draw.text((16, 14 + row * 78), line, fill=0, font=font)
    a = np.asarray(img, np.float32)[::-1] / 255.0          # row 0 = v = 0 (bottom)
    return np.repeat(a[..., None], 3, axis=-1) * 0.85 + 0.02


def _leaf_alpha(n: int = 64) -> np.ndarray:
    """A pointed leaf silhouette: 1 inside, 0 outside (binary, as a cut-out texture is)."""
    v, u = np.meshgrid(np.linspace(0, 1, n, endpoint=False) + 0.5 / n,
                       np.linspace(0, 1, n, endpoint=False) + 0.5 / n, indexing="ij")
    half_width = 0.42 * np.sin(np.pi * v) ** 1.3
    notch = 0.04 * (np.sin(10 * np.pi * v) > 0.6)
    return (np.abs(u - 0.5) < half_width - notch).astype(np.float32)


def pipe(tilted: bool = False) -> Scene:
    cam = Camera(position=(0.6, 0.9, 3.2), target=(0.0, 0.0, 0.0),
                 up=(0.25, 1.0, 0.0) if tilted else (0.0, 1.0, 0.0), yfov_deg=40, near=0.1, far=50)
    return Scene(
        name="pipe_tilted" if tilted else "pipe", resolution=QUICK, camera=cam, transport="direct",
        description="A brown pipe with hard edges in front of a wall" + (", skewed camera" if tilted else ""),
        stresses="long near-horizontal silhouette edges and the pipe's shading gradient",
        objects=(
            SceneObject(name="pipe", mesh=MeshSpec(kind="cylinder", size=(0.25, 3.0, 0), segments=48,
                                                    smooth=True),
                        material=Material(albedo=BROWN),
                        transform=Transform(rotate_axis=(0, 0, 1), rotate_deg=80)),
            _box("wall", (6.0, 4.0, 0.2), (0.0, 0.0, -1.0), WALL),
        ),
        lights=(SUN,), ambient=(0.15, 0.15, 0.16), background=SKY)


def text_wall() -> Scene:
    return Scene(
        name="text_wall", resolution=QUICK, transport="direct",
        description="A white wall with black letters (texture generated in code)",
        stresses="texture edges: hard black-on-white letter outlines under sub-pixel jitter",
        camera=Camera(position=(0.4, 0.3, 2.6), target=(0.0, 0.0, 0.0), yfov_deg=40, far=20),
        objects=(SceneObject(name="wall", mesh=MeshSpec(kind="plane", size=(4.0, 2.0, 0)),
                             material=Material(albedo=(1, 1, 1),
                                               texture=Texture(kind="array", data=_text_texture()))),),
        lights=(DirectionalLight(direction=(0.2, -0.3, -1.0), intensity=(0.9, 0.9, 0.9)),),
        ambient=(0.15, 0.15, 0.15), background=SKY)


def atrium() -> Scene:
    objs = [_box("floor", (8.0, 0.1, 8.0), (0.0, -0.05, 0.0), (0.55, 0.5, 0.45))]
    for i, x in enumerate((-2.4, -1.2, 0.0, 1.2, 2.4)):
        objs.append(_box(f"column_{i}", (0.25, 2.2, 0.25), (x, 1.1, -1.6), WALL))
        objs.append(_box(f"column_b{i}", (0.25, 2.2, 0.25), (x, 1.1, 1.6), WALL))
    objs.append(_box("beam", (5.4, 0.25, 0.3), (0.0, 2.3, -1.6), WALL))
    objs.append(_box("beam_b", (5.4, 0.25, 0.3), (0.0, 2.3, 1.6), WALL))
    objs.append(SceneObject(name="sphere", mesh=MeshSpec(kind="sphere", radius=0.45, segments=48, smooth=True),
                            material=Material(albedo=(0.7, 0.15, 0.1)), transform=Transform(translate=(0, 0.45, 0))))
    return Scene(
        name="atrium", resolution=QUICK, transport="direct_shadows",
        description="A courtyard of columns and beams with a static sphere, lit and shadowed",
        stresses="shadow edges and thin column silhouettes at several depths",
        camera=Camera(position=(0.5, 1.4, 4.6), target=(0.0, 0.8, 0.0), yfov_deg=50, far=40),
        objects=tuple(objs), lights=(SUN,), ambient=(0.2, 0.21, 0.24), background=SKY)


def flowers() -> Scene:
    rng = np.random.default_rng(7)
    leaf = Texture(kind="array", data=_leaf_alpha())
    objs = [_box("ground", (6.0, 0.1, 6.0), (0.0, -0.05, 0.0), (0.3, 0.25, 0.18))]
    for i in range(24):
        objs.append(SceneObject(
            name=f"leaf_{i}", mesh=MeshSpec(kind="plane", size=(0.35, 0.9, 0)),
            material=Material(albedo=tuple(float(c) for c in (0.1, 0.35 + 0.3 * rng.random(), 0.08)),
                              alpha=leaf),
            transform=Transform(translate=tuple(float(c) for c in (rng.uniform(-1.2, 1.2), 0.45,
                                                                  rng.uniform(-0.8, 0.8))),
                                rotate_axis=(0, 1, 0), rotate_deg=float(rng.uniform(0, 180)))))
    return Scene(
        name="flowers", resolution=QUICK, transport="direct_shadows",
        description="Alpha-cut-out foliage over soil, lit with shadows",
        stresses="alpha-tested edges that geometry-based edge detection cannot see",
        camera=Camera(position=(0.0, 1.0, 3.0), target=(0.0, 0.45, 0.0), yfov_deg=45, far=30),
        objects=tuple(objs), lights=(SUN,), ambient=(0.2, 0.22, 0.25), background=SKY)


def sphere_ghosting(frames: int = 100) -> Scene:
    objs = [_box("floor", (10.0, 0.1, 4.0), (0.0, -0.05, 0.0), (0.5, 0.5, 0.5)),
            _box("back_wall", (10.0, 3.0, 0.1), (0.0, 1.5, -2.0), (0.45, 0.5, 0.6))]
    for i, x in enumerate(np.linspace(-4, 4, 9)):
        objs.append(_box(f"pillar_{i}", (0.15, 3.0, 0.15), (float(x), 1.5, -1.6), WALL))
    objs.append(SceneObject(
        name="sphere", mesh=MeshSpec(kind="sphere", radius=0.4, segments=48, smooth=True),
        material=Material(albedo=(0.8, 0.7, 0.1)), transform=Transform(translate=(-3.0, 0.6, 0.0)),
        motion=Motion(velocity=(0.06, 0.0, 0.0), spin_axis=(0, 0, 1), spin_deg=-8.0)))
    return Scene(
        name="sphere_ghosting", resolution=QUICK, frames=frames, transport="direct",
        description="A sphere moving through a hall of pillars",
        stresses="ghosting behind a moving object; disocclusion of thin pillars",
        camera=Camera(position=(0.0, 1.2, 4.0), target=(0.0, 0.8, 0.0), yfov_deg=55, far=40),
        objects=tuple(objs), lights=(SUN, PointLight(position=(0.0, 2.5, 1.0), intensity=(1.0, 0.9, 0.8))),
        ambient=(0.15, 0.15, 0.18), background=SKY)


BUILTIN: dict[str, Callable[[], Scene]] = {
    "pipe": pipe,
    "pipe_tilted": lambda: pipe(tilted=True),
    "text_wall": text_wall,
    "atrium": atrium,
    "flowers": flowers,
    "sphere_ghosting": sphere_ghosting,
}
