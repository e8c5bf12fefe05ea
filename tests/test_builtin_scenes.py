"""The built-in scene library: every scene resolves, says what it is, has the features it
claims, stays within its geometry budget, and renders a small raster frame with finite colour.
Cheap by design: the agreement of raster and reference per scene is `taa-study agree --all`."""
import numpy as np
import pytest

from scenes import builtin_names, get_scene
from scenes.library import hard_cases, thesis

THESIS = ("pipe", "pipe_tilted", "blinds", "arched_window", "text_wall", "atrium", "flowers", "hard_edges",
          "sphere_ghosting", "hairball_unlit", "hairball_lit", "hairball_rotating_unlit", "hairball_rotating_lit")
HARD = ("subpixel_lines", "moire", "hdr_contrast", "fast_object", "disocclusion", "camera_cut")
MODERN = ("specular_shimmer", "specular_rail", "foliage_sway", "modern_mix", "texture_crawl")    # tests/test_modern_scenes.py


@pytest.fixture(scope="module")
def scenes():
    return {name: get_scene(name) for name in builtin_names()}


def test_every_named_scene_is_built_in(scenes):
    assert set(THESIS + HARD + MODERN) <= set(scenes)


@pytest.mark.parametrize("name", THESIS + HARD + MODERN)
def test_scene_is_described_at_both_resolutions(scenes, name):
    s = scenes[name]
    assert s.name == name
    assert s.resolution("quick") == (320, 180) and s.resolution("full") == (1600, 900)
    assert len(s.desc.description) > 20 and len(s.desc.stresses) > 20
    for m in s.meshes:
        assert np.all(np.isfinite(m.vertices)) and len(m.faces) > 0


def _max_emission(s):
    return max(max(o.material.emission) for o in s.desc.objects)


def test_claimed_features(scenes):
    f = {n: set(s.desc.features()) for n, s in scenes.items()}
    assert _max_emission(scenes["hdr_contrast"]) >= 1e3
    dark = min(max(o.material.albedo) for o in scenes["hdr_contrast"].desc.objects if not any(o.material.emission))
    assert dark * max(scenes["hdr_contrast"].desc.ambient) <= 2e-2          # ~1e-2 next to 1e3
    assert "camera_cut" in f["camera_cut"] and scenes["camera_cut"].is_cut(12) and not scenes["camera_cut"].is_cut(11)
    assert "texture" in f["moire"] and "texture" in f["disocclusion"] and "texture" in f["hard_edges"]
    for name in ("fast_object", "disocclusion", "hairball_rotating_unlit", "hairball_rotating_lit",
                 "sphere_ghosting"):
        assert "moving_object" in f[name], name
    assert {"direct_shadows", "shadows"} <= f["hairball_lit"] and f["hairball_unlit"] >= {"unlit"}
    assert "direct_shadows" in f["atrium"] and "unlit" in f["subpixel_lines"]
    assert scenes["hairball_rotating_lit"].desc.frames == 100 and scenes["disocclusion"].desc.frames >= 30
    for name in THESIS + HARD + MODERN:                    # static scenes have no motion; animated ones do
        s = scenes[name]
        moving = "moving_object" in f[name] or "moving_camera" in f[name]
        assert moving == (s.desc.frames > 1), name


def test_hairball_is_many_thin_fibres_within_budget(scenes):
    for name in ("hairball_unlit", "hairball_lit", "hairball_rotating_unlit", "hairball_rotating_lit"):
        s = scenes[name]
        tris = sum(len(m.faces) for m in s.meshes)
        assert 20000 < tris <= thesis.HAIRBALL_MAX_TRIANGLES
        assert len(s.meshes) <= 16                                            # a few meshes, not one per fibre
    assert thesis.hairball_paths().shape[0] >= 500


def test_rotating_hairball_spins_and_static_one_does_not(scenes):
    s = scenes["hairball_rotating_unlit"]
    assert not s.is_static(0) and scenes["hairball_unlit"].is_static(0)
    a, b = s.world_vertices(0, 0), s.world_vertices(0, 50)
    assert np.abs(a - b).max() > 0.5
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1), atol=1e-9)


def test_subpixel_lines_span_the_claimed_widths(scenes):
    s = scenes["subpixel_lines"]
    w, h = s.resolution("quick")
    cam = s.camera(0, w, h)
    quads = s.world_vertices(0, 0).reshape(-1, 4, 3)          # object 0: the lines, 4 corners each
    xy, _ = cam.project(quads.reshape(-1, 3))
    xy = xy.reshape(-1, 4, 2)
    widths = np.linalg.norm(xy[:, 3] - xy[:, 0], axis=1)
    assert widths.min() == pytest.approx(0.1, rel=0.02) and widths.max() == pytest.approx(1.5, rel=0.02)
    np.testing.assert_allclose(sorted(set(np.round(widths, 2))), hard_cases.LINE_WIDTHS_PX, rtol=0.02)
    assert np.all((xy >= 0) & (xy <= [w, h]))                 # every line is on screen


def test_fast_object_crosses_the_screen(scenes):
    s = scenes["fast_object"]
    w, h = s.resolution("quick")
    ball = [o.name for o in s.desc.objects].index("ball")
    xs = [s.camera(t, w, h).project(s.world_vertices(ball, t).mean(axis=0)[None])[0][0, 0]
          for t in (0, s.desc.frames - 1)]
    assert xs[0] < 0 and xs[1] > w and s.desc.frames <= 16            # off screen left to off screen right


def test_arch_is_finely_tessellated(scenes):
    assert thesis.ARCH_SEGMENTS >= 96


@pytest.mark.parametrize("name", THESIS + HARD + MODERN)
def test_one_small_raster_frame_renders(scenes, name):
    from raster import Rasterizer
    s = scenes[name]
    r = Rasterizer(s, 48, 27)
    try:
        out = r.render(s.desc.frames // 2, (0.0, 0.0), ("color",))["color"]
    finally:
        r.close()
    assert out.shape == (27, 48, 3) and np.all(np.isfinite(out)) and out.max() > 0
