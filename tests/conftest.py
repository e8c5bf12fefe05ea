import os
from pathlib import Path

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


def pytest_configure(config):
    config.addinivalue_line("markers", "long(seconds): a test of about that many seconds on a new 2-core "
                                       "machine; its file is started first (scheduling only)")


def pytest_collection_modifyitems(session, config, items):
    """The files of the longest tests first: pytest-xdist (--dist loadfile --no-loadscope-reorder)
    hands files out in this order, so no process is left alone with a long file at the end."""
    cost: dict = {}
    for item in items:
        m = item.get_closest_marker("long")
        if m is not None:
            cost[item.path] = cost.get(item.path, 0) + float(m.kwargs.get("seconds", m.args[0] if m.args else 1))
    order = {path: i for i, path in enumerate(dict.fromkeys(item.path for item in items))}
    items.sort(key=lambda it: (-cost.get(it.path, 0), order[it.path]))


class ReferencePool:
    """References an earlier test of this process rendered, for a later test whose subject is not
    the references: the cache is content-keyed (references/<scene>/<key>.exr), so a seeded test
    finds what it would have rendered itself as cache hits, and renders whatever else it asks for."""

    def __init__(self, root):
        self.root = root

    def seed(self, cache_root):
        """Copies every pooled reference into the cache under `cache_root`."""
        import shutil
        shutil.copytree(self.root, Path(cache_root) / "references", dirs_exist_ok=True)

    def keep(self, cache_root):
        """Adds the references of the cache under `cache_root` to the pool."""
        import shutil
        if (Path(cache_root) / "references").is_dir():
            shutil.copytree(Path(cache_root) / "references", self.root, dirs_exist_ok=True)


@pytest.fixture(scope="session")
def reference_pool(tmp_path_factory):
    return ReferencePool(tmp_path_factory.mktemp("reference_pool"))


@pytest.fixture
def no_plots(monkeypatch):
    """For a test whose studies read no plot: they draw none (study.reporting.report.PLOTS_ENV;
    every table, image, map and the HTML report are still written). Drawing the plots was about a
    third of a tiny study's CPU time; tests/test_html_report.py and the paper's tests draw them."""
    monkeypatch.setenv("TAA_STUDY_PLOTS", "0")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
