"""References on textured scenes: each set of samples is an Owen-scrambled Sobol' net,
so thin texel rows and columns are integrated to within a point or two per edge however they fall
in the pixel, the sets stay independent (the reported error stays honest), and a reference that
stops at the sample cap says how many samples its worst pixel would take."""
import functools
from pathlib import Path

import numpy as np
import pytest

from backend import dr, mi
from references import render_reference
from references.tracer import _PixelTracer, net_points
from scenes import get_scene
from scenes.description import Camera, Material, MeshSpec, Scene, SceneObject, Texture
from scenes.resolved import ResolvedScene
from shading import frame_geometry

EXAMPLES = Path(__file__).resolve().parent.parent / "scenes" / "examples" / "textured"
LSB = 1 / 255


@functools.lru_cache(maxsize=None)
def _example_reference(name: str, seed: int):
    """An example scene's frame 0 at 64 x 36 to the 2-LSB bound (the default sample cap): rendered
    once for the tests of this module that read it (a reference is a pure function of these)."""
    return render_reference(get_scene(str(EXAMPLES / f"{name}.toml")), 0, 64, 36, se_bound_lsb=2.0,
                            spp_per_pass=2, seed=seed)


def _points(a: int, seed0: int, seed1: int):
    u, v = net_points(dr.arange(mi.UInt32, a), mi.UInt32(seed0), mi.UInt32(seed1))
    return np.asarray(u, np.float64), np.asarray(v, np.float64)


@pytest.mark.parametrize("m", [0, 1, 4, 7, 11])
def test_a_set_is_a_net_one_point_in_every_cell_of_every_shape(m):
    """Hand count: for a set of 2^m points and every k, the 2^k x 2^(m-k) cells of [0,1)^2 hold
    exactly one point each (a jittered grid has that for one k only)."""
    a = 1 << m
    for seeds in ((0, 0), (1, 2), (0x9E3779B9, 0x7F4A7C15)):
        u, v = _points(a, *seeds)
        assert np.all((u >= 0) & (u < 1) & (v >= 0) & (v < 1))
        for k in range(m + 1):
            cell = np.floor(u * 2 ** k).astype(np.int64) * 2 ** (m - k) + np.floor(v * 2 ** (m - k)).astype(np.int64)
            assert np.array_equal(np.sort(cell), np.arange(a)), (seeds, k)


def test_scrambles_are_uniform_and_unrelated():
    """Over many scrambles every point of a set is uniform on [0,1)^2 (so every set's mean is
    unbiased), and the sets of two scrambles are unrelated (the replicates are independent)."""
    rng = np.random.default_rng(7)
    n, a = 4000, 8
    s = rng.integers(0, 1 << 32, size=(n, 2), dtype=np.uint64)
    j = dr.tile(dr.arange(mi.UInt32, a), n)
    u, v = net_points(j, dr.repeat(mi.UInt32(s[:, 0].astype(np.uint32)), a),
                      dr.repeat(mi.UInt32(s[:, 1].astype(np.uint32)), a))
    u, v = np.asarray(u).reshape(n, a), np.asarray(v).reshape(n, a)
    for x in (u, v):
        for p in range(a):              # each point: 16-bin histogram within 5 sd of n/16
            h = np.bincount(np.floor(x[:, p] * 16).astype(int), minlength=16)
            assert np.all(np.abs(h - n / 16) < 5 * np.sqrt(n / 16 * 15 / 16)), (p, h)
    # a set's estimate of a tilted thin band (area 0.05): unbiased, and consecutive scrambles'
    # estimates uncorrelated
    f = (np.abs(v - 0.37 - 0.3 * (u - 0.5)) < 0.025).mean(axis=1)
    assert abs(f.mean() - 0.05) < 4 * f.std() / np.sqrt(n)
    assert abs(np.corrcoef(f[:-1], f[1:])[0, 1]) < 4 / np.sqrt(n)


# Texel rows over a fronto-parallel plane that fills a 32 x 32 view: 480 rows, 15 per pixel, so
# the lines' edges fall at multiples of 1/15 of a pixel (no dyadic cell lines them up). White rows
# (mod 60, i.e. 4 pixels): {4, 5} in the first pixel, {22}, {37}, {54, 55}: symmetric under
# row -> 479 - row, so the texture's and the film's vertical conventions need not be known.
_ROWS, _PER_PX, _WHITE = 480, 15, (4, 5, 22, 37, 54, 55)


def _lines_scene(columns: bool) -> ResolvedScene:
    lines = np.isin(np.arange(_ROWS) % 60, _WHITE).astype(np.float32)
    tex = np.repeat(lines[:, None], 4, axis=1)            # (rows, 4): varies with v only
    if columns:
        tex = tex.T.copy()
    d, fov = 2.0, 40.0
    size = 2 * d * np.tan(np.radians(fov / 2))
    return ResolvedScene(Scene(
        name="texel_lines", transport="unlit", background=(0.0, 0.0, 0.0),
        camera=Camera(position=(0, 0, d), target=(0, 0, 0), yfov_deg=fov, near=0.1, far=10),
        objects=(SceneObject(name="wall", mesh=MeshSpec(kind="plane", size=(size, size, 0)),
                             material=Material(albedo=(1, 1, 1), texture=Texture(kind="array", data=tex))),)))


@pytest.mark.parametrize("columns", [False, True])
def test_sets_integrate_thin_texel_lines_to_within_two_samples(columns):
    """Through the tracer (camera, BVH, nearest-texel lookup): each pixel's exact value is its
    share of white texel rows (2/15 or 1/15), and every set of a samples, whatever its scramble,
    lands within 2/a of it (a band is a union of whole one-row cells of the net but for the two
    cells its edges cut). A jittered 16 x 16 grid of 256 misses by up to 1/16 (two cut rows of 16)."""
    w = h = 32
    scene = _lines_scene(columns)
    cam = scene.camera(0, w, h)
    tracer = _PixelTracer(scene, cam, False, None, None, frame_geometry(scene, 0))
    idx = np.arange(w * h)
    line = (idx % w) if columns else (idx // w)           # the pixel's row (or column) of the film
    exact = np.array([2, 1, 1, 2])[line % 4] / _PER_PX
    inner = (line > 0) & (line < 31)                       # the film's border rows meet the plane's edge
    for a in (16, 256, 1024):
        sums, lo, hi = tracer.sets(idx, 4, a, seed=11 + a)
        est = sums[..., 0] / a                             # (pixels, replicates)
        err = np.abs(est - exact[:, None])[inner]
        assert err.max() <= 2 / a + 1e-6, (a, err.max() * a)
        if a >= 256:       # a band of 1/15 px holds whole cells of 1/a: some sample sees it
            assert np.all(hi.max(1)[inner, 0] == 1) and np.all(lo.min(1)[inner, 0] == 0)


@pytest.mark.long(seconds=20)      # with the module's thin-lines references (the file's; scheduling only)
def test_a_reference_stopped_by_the_cap_says_what_it_would_take():
    """The thin-lines example at 64 x 36 with a 512-sample cap: pixels end over the bound, and the
    reference names the samples its worst pixel would take, more than the cap and more than each
    such pixel holds; with the default cap the same frame meets the bound and names none."""
    scene = get_scene(str(EXAMPLES / "thin_lines.toml"))
    capped = render_reference(scene, 0, 64, 36, se_bound_lsb=2.0, spp_per_pass=2, max_spp=512)
    assert capped.over_bound > 0 and capped.spp_needed > 512
    worst = capped.spp_map[capped.se_lsb > 2.0 * (1 + 1e-5)]
    assert worst.max() <= 512 < capped.spp_needed
    full = _example_reference("thin_lines", 0)        # seed 0, the default: the one the test below reads
    assert full.over_bound == 0 and full.spp_needed == 0


@pytest.mark.parametrize("name", ["checker_grazing", "thin_lines", "leaf"])
def test_textured_examples_meet_the_bound_and_their_error_is_honest(name):
    """Each example scene, two seeds at 64 x 36 (the cache's 8-sample pilot): every pixel within
    the bound below the cap, and the two references differ as their reported errors say, in the
    display domain of the converged image (the study's). Before the transform followed the mean,
    the bound was held in the domain of one 2-sample pass (thin lines: 4.4x the exposure) and 17 %
    of thin_lines' pixels were beyond 3.5 sigma, up to 15; a shared scramble across replicates
    would report an SE near 0."""
    from display import DisplayTransform
    a, b = (_example_reference(name, s) for s in (0, 1))
    assert a.over_bound == 0 and b.over_bound == 0 and a.spp_max > 256
    disp = DisplayTransform.from_reference(a.image)
    z = (np.abs(disp.encode(a.image) - disp.encode(b.image))
         / np.sqrt(a.display_stderr.astype(np.float64) ** 2 + b.display_stderr.astype(np.float64) ** 2 + 1e-12))
    # t with 31 degrees of freedom: 0.14 % of channels beyond 3.5, 0.01 % beyond 4.5
    assert np.mean(z.max(axis=-1) <= 3.5) >= 0.995 and np.mean(z.max(axis=-1) <= 4.5) >= 0.999, \
        np.sort(z.max(-1).ravel())[-8:]
    noisy = ((a.display_stderr > 0.01 * LSB) & (b.display_stderr > 0.01 * LSB)
             & (a.display_floor < a.display_stderr) & (b.display_floor < b.display_stderr))
    assert noisy.any(-1).sum() > 100
    assert 0.5 < np.median(z[noisy]) < 0.9, np.median(z[noisy])


def test_a_grey_array_texture_is_every_channel():
    """An (H, W) array texture (documented) reads as its value in R, G and B, as the (H, W, 3)
    array of the same values does; it was stored with one value per texel and read as three."""
    from references import trace_pixel_centres
    grey = _lines_scene(False)
    tex = grey.desc.objects[0].material.texture
    rgb_desc = grey.desc.model_copy(update={"objects": (grey.desc.objects[0].model_copy(update={
        "material": Material(albedo=(1, 1, 1), texture=Texture(kind="array", data=np.repeat(tex.data[..., None], 3, -1)))}),)})
    a, _, _ = trace_pixel_centres(grey, 0, 32, 32)
    b, _, _ = trace_pixel_centres(ResolvedScene(rgb_desc), 0, 32, 32)
    assert np.isin(a, (0.0, 1.0)).all() and a.max() == 1.0
    np.testing.assert_array_equal(a, b)
