import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
# The suite already runs a process per core (pytest-xdist): its studies run in-process unless a
# test names an executor; tests/test_study_graph.py tests the default (auto) and the clusters.
os.environ.setdefault("TAA_STUDY_WORKERS", "1")

import backend  # noqa: E402,F401  (selects libLLVM before drjit is imported anywhere)
from scenes.description import (Camera, DirectionalLight, Material, MeshSpec, Motion,  # noqa: E402
                                Scene, SceneObject, Transform)
from scenes.resolved import ResolvedScene  # noqa: E402


def quad_object(name, size, at, albedo, rotate_deg=0.0, axis=(0, 0, 1), motion=None):
    return SceneObject(name=name, mesh=MeshSpec(kind="plane", size=(size[0], size[1], 0)),
                       material=Material(albedo=albedo),
                       transform=Transform(translate=at, rotate_axis=axis, rotate_deg=rotate_deg),
                       motion=motion or Motion())


def two_colour_scene(rotate_deg=17.0, transport="unlit", **cam):
    """A red quad, tilted in the image plane, in front of a blue backdrop; camera looks down -z."""
    camera = Camera(position=(0, 0, 5), target=(0, 0, 0), yfov_deg=30, near=0.5, far=50, **cam)
    return ResolvedScene(Scene(
        name="two_colour", transport=transport, camera=camera,
        objects=(quad_object("front", (1.2, 1.2), (0.1, 0.0, 0.5), (1.0, 0.0, 0.0), rotate_deg),
                 quad_object("back", (20, 20), (0, 0, -1), (0.0, 0.0, 1.0))),
        lights=(DirectionalLight(direction=(0, 0, -1)),) if transport != "unlit" else ()))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
