"""Built-in scenes, rebuilt procedurally after the thesis's test scenes (Oliveros 2018,
Improved Sampling for Temporal Anti-Aliasing, §5.2).

The first few are defined here; the rest of the thesis scenes and the hard cases live in
scenes/library/ and are registered in BUILTIN below."""
from __future__ import annotations

from typing import Callable

import numpy as np

from .description import (Camera, DirectionalLight, Material, MeshSpec, Motion, PointLight, Scene,
                          SceneObject, Texture, Transform)
from .library import hard_cases, modern, thesis
from .library.common import BLUE, BROWN, QUICK, SKY, SUN, WALL, _box, _leaf_alpha, _text_texture  # noqa: F401


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
    "atrium": thesis.atrium,
    "flowers": flowers,
    "sphere_ghosting": sphere_ghosting,
    # thesis scenes (scenes/library/thesis.py)
    "blinds": thesis.blinds,
    "arched_window": thesis.arched,
    "hard_edges": thesis.hard_edges,
    "hairball_unlit": lambda: thesis.hairball(lit=False, rotating=False),
    "hairball_lit": lambda: thesis.hairball(lit=True, rotating=False),
    "hairball_rotating_unlit": lambda: thesis.hairball(lit=False, rotating=True),
    "hairball_rotating_lit": lambda: thesis.hairball(lit=True, rotating=True),
    # hard cases (scenes/library/hard_cases.py)
    "subpixel_lines": hard_cases.subpixel_lines,
    "moire": hard_cases.moire,
    "hdr_contrast": hard_cases.hdr_contrast,
    "fast_object": hard_cases.fast_object,
    "disocclusion": hard_cases.disocclusion,
    "camera_cut": hard_cases.camera_cut,
    # today's hard cases: glossy metal and moving cut-outs (scenes/library/modern.py)
    "specular_shimmer": modern.specular_shimmer,
    "specular_rail": modern.specular_rail,
    "foliage_sway": modern.foliage_sway,
    "modern_mix": modern.modern_mix,
    "texture_crawl": modern.texture_crawl,
}
