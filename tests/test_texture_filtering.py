"""Filtered textures (docs/method.md, "Texture filtering"): the mip chain, the level a pixel's UV
footprint selects, non-power-of-two and 1x1 textures, and raster-reference agreement."""
import numpy as np
import pytest

from backend import dr, mi
from raster import Rasterizer
from raster.visibility import RasterError
from references import ReferenceCache
from scenes.description import Scene
from scenes.resolved import ResolvedScene
from shading.mips import lod, mip_chain, mip_table, next_level
from shading.texels import filtered


def test_each_even_level_is_the_2x2_box_of_the_one_above_and_keeps_the_mean():
    rng = np.random.default_rng(0)
    tex = rng.random((16, 8, 3)).astype(np.float32)
    chain = mip_chain(tex)
    assert [lv.shape[:2] for lv in chain] == [(16, 8), (8, 4), (4, 2), (2, 1), (1, 1)]
    for above, below in zip(chain[:3], chain[1:4]):
        h, w = above.shape[:2]
        box = above.astype(np.float64).reshape(h // 2, 2, w // 2, 2, 3).mean(axis=(1, 3))
        np.testing.assert_allclose(below, box, atol=2e-7)
    for lv in chain:
        np.testing.assert_allclose(lv.mean(axis=(0, 1)), tex.astype(np.float64).mean(axis=(0, 1)), atol=1e-6)


def test_non_power_of_two_and_1x1_chains():
    # floor halving: 5x3 -> 2x1 -> 1x1; texel i of a 2-wide level covers [2.5 i, 2.5 (i + 1)) above
    tex = np.arange(15, dtype=np.float32).reshape(3, 5, 1)
    chain = mip_chain(tex)
    assert [lv.shape[:2] for lv in chain] == [(3, 5), (1, 2), (1, 1)]
    cols = tex[..., 0].mean(axis=0)                      # 5, 6, 7, 8, 9
    left = (cols[0] + cols[1] + 0.5 * cols[2]) / 2.5
    right = (0.5 * cols[2] + cols[3] + cols[4]) / 2.5
    np.testing.assert_allclose(chain[1][0, :, 0], [left, right], rtol=1e-6)
    assert chain[2][0, 0, 0] == pytest.approx(tex.mean(), rel=1e-6)   # the mean, odd sizes too
    one = np.full((1, 1, 3), 0.25, np.float32)
    assert len(mip_chain(one)) == 1 and np.array_equal(mip_chain(one)[0], one)
    assert next_level(np.ones((1, 7, 1), np.float32)).shape == (1, 3, 1)


def _bilinear_np(lv, u, v):
    h, w = lv.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    at = lambda i, j: lv[j % h, i % w].astype(np.float64)   # noqa: E731
    return ((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0))
            + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1)))


@pytest.mark.parametrize("rho,bias", [(4.0, 0.0), (4.0, 0.5), (5.3, -1.2), (0.5, 0.0), (1e4, 0.0)])
def test_a_trilinear_lookup_blends_the_levels_the_formula_picks(rho, bias):
    rng = np.random.default_rng(1)
    tex = rng.random((32, 24, 3)).astype(np.float32)       # 24 wide: a 3-texel level on the way
    chain = mip_chain(tex)
    table = mip_table([tex], ["trilinear"], 3)
    u, v = 0.3712, 0.6189
    # a footprint of rho base texels along x (du/dx = rho / W), half that along y
    dudx, dvdy = rho / 24, 0.5 * rho / 32
    lam = lod((dudx, 0.0), (0.0, dvdy), 24, 32, bias)
    assert lam == pytest.approx(np.log2(rho) + bias)
    lam = min(max(lam, 0.0), len(chain) - 1)
    l0 = int(np.floor(lam))
    l1, f = min(l0 + 1, len(chain) - 1), lam - l0
    want = (1 - f) * _bilinear_np(chain[l0], u, v) + f * _bilinear_np(chain[l1], u, v)
    foot = ((mi.Float(dudx), mi.Float(0.0), mi.Float(0.0), mi.Float(dvdy)), mi.Float(bias))
    has, got = filtered(table, mi.UInt32(1), mi.Point2f(u, v), 3, mi.Bool(True), foot)
    assert bool(has[0])
    np.testing.assert_allclose([float(c[0]) for c in got], want, rtol=2e-5, atol=2e-6)


def _head_on(filt: str, squares: int = 64, size: int = 32, own_bias: float = 0.0):
    """An unlit plane filling a 90-degree view from distance 1: 2 world units over `size` pixels,
    a 1-texel checker of `squares` texels over them: squares / size texels per pixel."""
    d = {"name": "head_on", "transport": "unlit", "camera": {"position": [0, 0, 1], "target": [0, 0, 0], "yfov_deg": 90},
         "objects": [{"name": "p", "mesh": {"kind": "plane", "size": [2.0, 2.0, 1.0]},
                      "material": {"albedo": [1, 1, 1], "texture": {"kind": "checker", "squares": squares,
                                                                    "filter": filt, "lod_bias": own_bias}}}]}
    return ResolvedScene(Scene.model_validate(d))


def test_the_raster_footprint_selects_log2_texels_per_pixel_plus_bias():
    # 2 texels per pixel: lambda = log2 2 + bias. Level 1, the 2x2 box of a 1-texel checker, is 0.5
    # everywhere; the samples sit on texel centres (jitter 1/4 pixel = 1/2 texel), where level 0 is
    # exactly 0 or 1: the result is (1 - f) L0 + f 0.5 with f = clip(1 + bias, 0, 1)
    r = Rasterizer(_head_on("trilinear"), 32, 32)
    try:
        got = {}
        for bias in (-3.0, -1.0, -0.75, -0.5, -0.2, 0.0, 0.7):
            r.lod_bias = bias
            got[bias] = r.render(0, (0.25, 0.25), ("color",))["color"][..., 0]
    finally:
        r.close()
    level0 = got[-1.0]
    assert set(np.unique(level0).tolist()) <= {0.0, 1.0} and np.array_equal(level0, got[-3.0])
    for bias, c in got.items():
        f = min(max(1.0 + bias, 0.0), 1.0)
        np.testing.assert_allclose(c, (1 - f) * level0 + 0.5 * f, atol=2e-5, err_msg=f"bias {bias}")


def test_a_textures_own_bias_adds_to_the_columns_and_is_checked():
    imgs = []
    for own, col in ((-0.5, 0.0), (0.0, -0.5), (-0.25, -0.25), (0.0, 0.0)):
        r = Rasterizer(_head_on("trilinear", own_bias=own), 32, 32, lod_bias=col)
        imgs.append(r.render(0, (0.25, 0.25), ("color",))["color"])
        r.close()
    np.testing.assert_allclose(imgs[0], imgs[1], atol=1e-6)
    np.testing.assert_allclose(imgs[2], imgs[1], atol=1e-6)
    assert np.abs(imgs[3] - imgs[0]).max() > 0.2
    with pytest.raises(ValueError, match="lod_bias applies to filter 'trilinear' only"):
        _head_on("bilinear", own_bias=-1.0)
    with pytest.raises(ValueError, match="greater than or equal to -4"):
        _head_on("trilinear", own_bias=-4.5)


def test_nearest_and_mip_free_rasters_ignore_the_bias_and_a_non_finite_bias_is_refused():
    for filt, mipmaps in (("nearest", True), ("trilinear", False)):
        imgs = []
        for bias in (0.0, -2.0):
            r = Rasterizer(_head_on(filt), 32, 32, lod_bias=bias, mipmaps=mipmaps)
            imgs.append(r.render(0, (0.25, 0.25), ("color",))["color"])
            r.close()
        assert np.array_equal(*imgs) and set(np.unique(imgs[0]).tolist()) <= {0.0, 1.0}
    with pytest.raises(RasterError, match="lod_bias"):
        Rasterizer(_head_on("trilinear"), 32, 32, lod_bias=float("nan"))


def test_non_power_of_two_and_1x1_textures_render_finite():
    rng = np.random.default_rng(2)
    for shape in ((37, 23, 3), (1, 1, 3), (1, 9, 3)):
        d = {"name": "npot", "transport": "unlit", "camera": {"position": [0, 0.3, 1], "target": [0, 0, -1]},
             "objects": [{"name": "p", "mesh": {"kind": "plane", "size": [4.0, 4.0, 1.0], "uv_scale": [3.0, 3.0]},
                          "material": {"texture": {"kind": "array", "data": rng.random(shape).astype(np.float32),
                                                   "filter": "trilinear"}},
                          "transform": {"rotate_axis": [1, 0, 0], "rotate_deg": -90.0}}]}
        r = Rasterizer(ResolvedScene(Scene.model_validate(d)), 32, 18)
        c = r.render(0, (0.1, -0.2), ("color",))["color"]
        r.close()
        assert np.isfinite(c).all() and c.max() <= 1.0


def test_a_filtered_scene_keeps_a_nearest_scenes_hash_when_nearest():
    a, b = _head_on("nearest").content_hash, _head_on("trilinear").content_hash
    d = Scene.model_validate({"name": "x", "transport": "unlit", "camera": {"position": [0, 0, 1], "target": [0, 0, 0]},
                              "objects": [{"name": "p", "mesh": {"kind": "plane"},
                                           "material": {"texture": {"kind": "checker"}}}]})
    assert "filter" not in d.model_dump(mode="json")["objects"][0]["material"]["texture"] and a != b


def test_trilinear_scene_meets_the_agreement_targets(tmp_path):
    """The agreement check (mip-free bilinear raster against the reference's base-level integral)."""
    from study.engine.agreement import TARGETS, check_agreement
    rng = np.random.default_rng(3)
    tex = rng.uniform(0.05, 0.95, (64, 77, 3)).astype(np.float32)
    d = {"name": "tri_floor", "transport": "direct", "ambient": [0.3, 0.3, 0.3], "background": [0.2, 0.3, 0.4],
         "camera": {"position": [0.0, 0.35, 1.2], "target": [0.0, 0.0, -1.0]},
         "objects": [{"name": "floor", "mesh": {"kind": "plane", "size": [3.0, 3.0, 1.0], "uv_scale": [2.0, 2.0]},
                      "material": {"texture": {"kind": "array", "data": tex, "filter": "trilinear"}},
                      "transform": {"rotate_axis": [1, 0, 0], "rotate_deg": -90.0}}],
         "lights": [{"type": "directional", "direction": [-0.3, -1.0, -0.4], "intensity": [0.8, 0.8, 0.8]}]}
    a = check_agreement(ResolvedScene(Scene.model_validate(d)), 48, 27, samples=64, cache=ReferenceCache(tmp_path),
                        progress=False, se_bound_lsb=1.0, target_noise_db=0.0)
    print(f"agreement {a.agreement_psnr_db:.2f} dB, interior max err {a.interior_max_abs_err:.2e}")
    assert a.agreement_psnr_db >= TARGETS["agreement_psnr_db"]
    assert a.interior_max_abs_err <= TARGETS["interior_max_abs_err"]


def test_a_nearest_object_beside_a_trilinear_one_renders_as_in_an_all_nearest_scene():
    def two(right: str):
        objs = [{"name": n, "mesh": {"kind": "plane", "size": [1.0, 2.0, 1.0]},
                 "material": {"texture": {"kind": "checker", "squares": 48, "filter": f}},
                 "transform": {"translate": [x, 0.0, 0.0], "rotate_axis": [1, 0, 0], "rotate_deg": -70.0}}
                for n, f, x in (("left", "nearest", -0.5), ("right", right, 0.5))]
        d = {"name": "two", "transport": "unlit", "camera": {"position": [0, 0, 1.5], "target": [0, 0, 0]},
             "objects": objs}
        r = Rasterizer(ResolvedScene(Scene.model_validate(d)), 48, 27)
        out = r.render(0, (0.1, 0.3), ("color", "object_id"))
        r.close()
        return out
    a, b = two("nearest"), two("trilinear")
    left, right = a["object_id"] == 1, a["object_id"] == 2
    assert left.sum() > 50 and right.sum() > 50 and np.array_equal(a["object_id"], b["object_id"])
    assert np.array_equal(a["color"][left], b["color"][left])
    assert not np.array_equal(a["color"][right], b["color"][right])


def test_transport_path_samples_a_filtered_texture_as_the_direct_reference_does():
    """Mitsuba's path tracer (depth 2: direct light only) on a bilinear texture equals our
    bilinear lookup; with Mitsuba's nearest bitmap it would not (25 dB apart here)."""
    from references.render import render_reference
    tex = np.random.default_rng(5).uniform(0.05, 0.95, (8, 8, 3)).astype(np.float32)

    def ref(transport):
        d = {"name": f"p_{transport}", "transport": transport, "path_max_depth": 2,
             "camera": {"position": [0.0, 1.2, 1.2], "target": [0.0, 0.0, 0.0], "yfov_deg": 40},
             "objects": [{"name": "floor", "mesh": {"kind": "plane", "size": [2.0, 2.0, 1.0]},
                          "material": {"texture": {"kind": "array", "data": tex, "filter": "bilinear"}},
                          "transform": {"rotate_axis": [1, 0, 0], "rotate_deg": -90.0}}],
             "lights": [{"type": "directional", "direction": [-0.3, -1.0, -0.4], "intensity": [0.8, 0.8, 0.8]}]}
        return render_reference(ResolvedScene(Scene.model_validate(d)), 0, 24, 16, se_bound_lsb=4.0,
                                target_noise_db=0.0, max_spp=256).image
    a, b = ref("path"), ref("direct_shadows")
    psnr = 10 * np.log10(1 / np.mean((np.clip(a, 0, 1) - np.clip(b, 0, 1)) ** 2))
    assert psnr > 80, psnr
