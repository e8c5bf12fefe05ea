
import numpy as np
import pytest

import references.exr as exr_mod
from backend import mi
from conftest import two_colour_scene
from references import ReferenceCache, render_reference, trace_pixel_centres
from references.mitsuba_scene import sensor
from scenes import get_scene


def test_mitsuba_camera_matches_ours():
    scene = get_scene("atrium")
    cam = scene.camera(0, 80, 45)
    pts = np.array([[0.3, 1.0, 0.2], [-2.0, 0.5, -1.5], [1.5, 2.2, 1.0]])
    img, depth = cam.project(pts)
    s = sensor(cam, 1)
    ray, _ = s.sample_ray(0.0, 0.5, mi.Point2f(mi.Float(img[:, 0] / 80), mi.Float(img[:, 1] / 45)),
                          mi.Point2f(0.5, 0.5))
    d = np.array([np.asarray(ray.d[k]) for k in range(3)]).T
    want = pts - cam.position
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    np.testing.assert_allclose(d, want, atol=2e-6)
    assert np.all(depth > 0)


def test_pixel_centre_rays_match_raster_colours_exactly_in_flat_regions():
    from raster import Rasterizer
    scene = two_colour_scene(transport="direct")
    rgb, ids, prims = trace_pixel_centres(scene, 0, 40, 30)
    r = Rasterizer(scene, 40, 30)
    try:
        b = r.render(0, (0, 0), ("color", "object_id", "prim_id"))
    finally:
        r.close()
    same = ids == b["object_id"]
    assert same.mean() > 0.99
    assert np.mean(prims[same] == b["prim_id"][same]) > 0.99      # the same triangle, too
    np.testing.assert_allclose(rgb[same], b["color"][same], atol=1e-6)


def test_bound_is_met_and_recorded():
    scene = two_colour_scene(rotate_deg=23)
    lo = render_reference(scene, 0, 32, 24, se_bound_lsb=2.0)
    hi = render_reference(scene, 0, 32, 24, se_bound_lsb=0.5)
    assert lo.over_bound == 0 and lo.se_max_lsb <= 2.0 * (1 + 1e-5)
    for ref, bound in ((lo, 2.0), (hi, 0.5)):
        # pixels still over the bound are counted, and only those that hit the sample cap
        over = ref.se_lsb > bound * (1 + 1e-5)
        assert ref.over_bound == over.sum() and np.all(ref.spp_map[over] >= (1 << 16) - 32)
        assert ref.bound_lsb == bound and ref.spp_map.shape == (24, 32)
        assert ref.spp == round(ref.spp_mean) and ref.spp_max == ref.spp_map.max()
    assert hi.spp_mean > lo.spp_mean
    # interior pixels are noise-free (one shading value over the whole pixel): pilot samples only
    assert lo.stderr[12, 2].max() == 0.0 and lo.display_stderr[12, 2].max() == 0.0
    assert lo.spp_map[12, 2] == 16
    # the quad's coverage of an edge pixel is between the two pure colours
    assert np.all(lo.image >= 0) and np.all(lo.image <= 1.0 + 1e-6)


def test_cache_reads_back_detects_corruption_and_leaves_no_partial_file(tmp_path, monkeypatch):
    scene = two_colour_scene()
    logs = []
    cache = ReferenceCache(tmp_path, log=logs.append)
    a, cached = cache.get(scene, 0, 24, 16, target_noise_db=50)
    assert not cached
    b, cached = cache.get(scene, 0, 24, 16, target_noise_db=50)
    assert cached and np.array_equal(a.image, b.image) and b.spp == a.spp
    path = cache.path(scene, a.key)
    import OpenEXR
    h = OpenEXR.File(str(path), header_only=True).header()
    assert h["taa_spp"] == a.spp and h["taa_scene_hash"] == scene.content_hash
    assert abs(h["taa_noise_psnr_db"] - a.noise_psnr_db) < 1e-4   # stored as float32
    assert h["taa_bound_lsb"] == 0.5 and h["taa_spp_max"] == a.spp_max and h["taa_over_bound"] == a.over_bound
    assert abs(h["taa_se_max_lsb"] - a.se_max_lsb) < 1e-4 and abs(h["taa_spp_mean"] - a.spp_mean) < 1e-3
    # per-pixel spp and both standard errors come back as channels
    assert np.array_equal(b.spp_map, a.spp_map) and np.array_equal(b.display_stderr, a.display_stderr)
    assert np.array_equal(b.stderr, a.stderr) and b.spp_max > b.spp_map.min()

    # A truncated file is detected, reported, removed and rendered again.
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    c, cached = cache.get(scene, 0, 24, 16, target_noise_db=50)
    assert not cached and np.array_equal(c.image, a.image)
    assert any("corrupt" in m for m in logs)

    # A different target is a different reference.
    d, cached = cache.get(scene, 0, 24, 16, target_noise_db=52)
    assert not cached and d.key != a.key

    # An interrupted render leaves nothing behind.
    def boom(*args, **kw):
        raise KeyboardInterrupt
    monkeypatch.setattr(exr_mod.OpenEXR.File, "write", lambda self, p: (open(p, "wb").write(b"xx"), boom()))
    with pytest.raises(KeyboardInterrupt):
        cache.get(scene, 0, 24, 16, target_noise_db=55)
    names = sorted(p.name for p in path.parent.iterdir())
    assert not any(n.endswith(".part") for n in names)
    # the two complete references only, each with its display record (references.cache)
    assert [n for n in names if n.endswith(".exr")] == sorted(cache.path(scene, r.key).name for r in (a, d))
    assert [n for n in names if n.endswith(".display.json")] == sorted(
        cache.path(scene, r.key).stem + ".display.json" for r in (a, d))
    assert len(names) == 4


def test_cache_key_covers_the_display_code(tmp_path):
    """The stopping rule measures noise through the display transform, so its source is keyed."""
    import shutil
    from pathlib import Path
    from references.cache import _CODE_FILES, code_version
    root = Path(__file__).resolve().parent.parent
    for rel in _CODE_FILES:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(root / rel, tmp_path / rel)
    assert code_version(tmp_path) == code_version()
    disp = tmp_path / "display" / "__init__.py"
    disp.write_text(disp.read_text() + "\n# changed\n")
    assert code_version(tmp_path) != code_version()


def test_path_tracer_with_one_bounce_equals_direct_shadows():
    """Mitsuba's own path tracer, limited to direct light and with no ambient, must reproduce our
    direct_shadows shading (the pi scaling of lights, two-sided BSDFs, textures, background)."""
    from display import DisplayTransform, psnr
    from scenes.resolved import ResolvedScene
    for name in ("atrium", "text_wall"):
        d = get_scene(name).desc.model_copy(update={"ambient": (0.0, 0.0, 0.0)})
        direct = render_reference(ResolvedScene(d.model_copy(update={"transport": "direct_shadows"})),
                                  0, 48, 27, target_noise_db=50)
        path = render_reference(ResolvedScene(d.model_copy(update={"transport": "path", "path_max_depth": 2})),
                                0, 48, 27, target_noise_db=50)
        disp = DisplayTransform.from_reference(direct.image)
        assert psnr(disp.encode(direct.image), disp.encode(path.image)) > 55, name


def test_path_transport_with_cutouts_is_refused_clearly():
    from scenes.resolved import ResolvedScene
    s = ResolvedScene(get_scene("flowers").desc.model_copy(update={"transport": "path"}))
    with pytest.raises(Exception, match="alpha cut-outs"):
        render_reference(s, 0, 8, 8)
