"""Ferrando's TAA (Ferrando 2018, taa_impl/ferrando.py): camera-only motion from depth, the fixed-weight
blend, and both clamp variants, by hand."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)

import taa_impl
from scenes.camera import CameraState, look_at
from taa_impl.ferrando import FerrandoTAA, motion_from_depth

F = np.float32
FAR = 50.0
W, H = 24, 16
NAMES = {"taa_ferrando_text": (0.95, "current"), "taa_ferrando_code": (0.6, "history"),
         "taa_ferrando_code_noclamp": (0.3, "none")}


def cam(pos, target, w=W, h=H, yfov=40.0):
    return CameraState(look_at(pos, target, (0, 1, 0)), yfov, 0.5, FAR, w, h)


# a tilted plane through the origin; the camera moves and turns between the two frames
NORMAL = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
PREV = cam((0.3, 0.2, 5.0), (0.0, 0.0, 0.0))
CUR = cam((1.0, 0.3, 4.6), (0.5, -0.2, 0.0))


def plane_hits(camera):
    """Per-pixel-centre depth (ray parameter of a unit-view-axis ray) and world point on the plane."""
    ys, xs = np.indices((camera.height, camera.width))
    d = camera.ray_directions(xs.ravel() + 0.5, ys.ravel() + 0.5)
    eye = camera.position
    t = (NORMAL @ (np.zeros(3) - eye)) / (d @ NORMAL)
    return t.reshape(camera.height, camera.width), eye + t[:, None] * d


def pattern(points):
    """A smooth colour field on the plane (linear in world x, y)."""
    x, y = points[:, 0], points[:, 1]
    return np.stack([0.5 + 0.2 * x, 0.4 + 0.15 * y, 0.5 + 0.1 * (x - y)], -1)


def frame_for(camera):
    depth, pts = plane_hits(camera)
    colour = pattern(pts).reshape(camera.height, camera.width, 3)
    return dict(color=colour.astype(F), depth=depth.astype(F))


def step(tech, frame, cams, reset=False):
    return tech.process(frame, jitter=(0.0, 0.0), far=FAR, reset=reset, cameras=cams)


def test_registry_and_params():
    for name, (k, clamp) in NAMES.items():
        t = taa_impl.make(name)
        assert isinstance(t, FerrandoTAA) and t.name == name
        assert (t.params.history_weight, t.params.clamp) == (k, clamp)
        assert t.sampling == "sequence" and t.output_space == "linear" and t.inputs.cameras
        assert t.needs == {"color", "depth"}
        assert taa_impl.TECHNIQUES[name].needs == {"color", "depth"}
    b = taa_impl.make("taa_ferrando_text", motion_source="buffer")
    assert b.needs == {"color", "motion"} and not b.inputs.cameras
    for bad in ({"history_weight": 1.5}, {"clamp": "box"}, {"motion_source": "x"},
                {"offscreen": "wrap"}, {"sharpen": "strong"}):
        with pytest.raises(ValueError):
            taa_impl.make("taa_ferrando_text", **bad)
    with pytest.raises(ValueError):
        taa_impl.make("taa_ferrando_text", feedback="inside")   # no luminance feedback here


def test_depth_motion_equals_exact_motion_of_a_still_scene():
    depth, pts = plane_hits(CUR)
    # the test's own geometry: the points project back onto the pixel centres at that depth
    xy, z = CUR.project(pts)
    ys, xs = np.indices((H, W))
    np.testing.assert_allclose(xy, np.c_[xs.ravel() + 0.5, ys.ravel() + 0.5], atol=1e-9)
    np.testing.assert_allclose(z, depth.ravel(), rtol=1e-12)
    prev_xy, _ = PREV.project(pts)
    exact = (np.c_[xs.ravel() + 0.5, ys.ravel() + 0.5] - prev_xy).reshape(H, W, 2)
    assert np.abs(exact).max() > 2.0                     # a real camera motion
    got = motion_from_depth(depth.astype(F), CUR, PREV)
    np.testing.assert_allclose(got, exact, atol=2e-3)
    # the technique reprojects with exactly that motion
    t = taa_impl.make("taa_ferrando_text")
    step(t, frame_for(CUR), (CUR, PREV))
    np.testing.assert_array_equal(t.debug_terms()["velocity"], got)
    # identical cameras: exactly zero motion
    assert not np.any(motion_from_depth(depth.astype(F), CUR, CUR))
    # a point behind the previous camera: previous position off-screen
    behind = cam((0.0, 0.0, -3.0), (0.0, 0.0, -10.0))   # looks away from the plane
    m = motion_from_depth(depth.astype(F), CUR, behind)
    prev_x = xs + 0.5 - m[..., 0]
    assert np.all(prev_x < 0)


def test_reprojection_follows_the_camera():
    """History weight 1 and no clamp: the output is the history fetched where the surface point was,
    which must be the current colour of that point (up to bilinear error on a smooth field)."""
    t = taa_impl.make("taa_ferrando_code_noclamp", history_weight=1.0)
    step(t, frame_for(PREV), (PREV, PREV))
    cur = frame_for(CUR)
    out = step(t, cur, (CUR, PREV))
    terms = t.debug_terms()
    assert 0.3 < (terms["history_valid"] > 0).mean() < 1.0
    ys, xs = np.indices((H, W))
    px, py = xs + 0.5 - terms["velocity"][..., 0], ys + 0.5 - terms["velocity"][..., 1]
    valid = (px > 1) & (px < W - 1) & (py > 1) & (py < H - 1)   # away from the clamped border
    assert valid.mean() > 0.3
    np.testing.assert_allclose(out[valid], cur["color"][valid], atol=1e-3)
    # Ferrando's sign (history at pixel + motion) would miss by a lot
    wrong = taa_impl.make("taa_ferrando_code_noclamp", history_weight=1.0, motion_source="buffer")
    first = frame_for(PREV)
    first["motion"] = np.zeros((H, W, 2), F)
    wrong.process(first, jitter=(0, 0), far=FAR)
    cur_b = dict(cur, motion=-motion_from_depth(cur["depth"], CUR, PREV))
    out_w = wrong.process(cur_b, jitter=(0, 0), far=FAR)
    assert np.abs(out_w - cur["color"])[valid].max() > 20 * np.abs(out - cur["color"])[valid].max()


@pytest.mark.parametrize("name", sorted(NAMES))
@pytest.mark.parametrize("sharpen", ["none", "xu"])
def test_constant_image_stays_constant(name, sharpen):
    t = taa_impl.make(name, sharpen=sharpen)
    cams = [PREV, CUR, cam((0.9, 0.0, 4.5), (0.3, 0.0, 0.0)), CUR]
    for i, c in enumerate(cams):
        fr = frame_for(c)
        fr["color"] = np.full((H, W, 3), (0.3, 1.7, 0.02), F)
        out = step(t, fr, (c, cams[i - 1] if i else c))
        np.testing.assert_array_equal(out, fr["color"])
        np.testing.assert_array_equal(t.history, fr["color"])


@pytest.mark.parametrize("name,weight", [("taa_ferrando_text", 0.95), ("taa_ferrando_code", 0.6),
                                         ("taa_ferrando_code_noclamp", 0.3)])
def test_fixed_weight_blend_by_hand(name, weight):
    """h = 1, c = 0: out = mix(c, h, k) = k (no luminance feedback). The text preset's current-
    neighbourhood clamp would pull h to 0 on an all-0 frame, so it runs with clamp='none' here."""
    over = {"clamp": "none"} if name == "taa_ferrando_text" else {}
    t = taa_impl.make(name, **over)
    fr = frame_for(CUR)
    fr["color"] = np.ones((H, W, 3), F)
    step(t, fr, (CUR, CUR))
    fr["color"] = np.zeros((H, W, 3), F)
    out = step(t, fr, (CUR, CUR))
    np.testing.assert_allclose(out, weight, rtol=0, atol=1e-7)
    out2 = step(t, fr, (CUR, CUR))                        # and again: k^2
    np.testing.assert_allclose(out2, weight * weight, rtol=0, atol=1e-7)
    # with the text's clamp the box of an all-0 frame is [0, 0]: the history is clamped away
    t2 = taa_impl.make("taa_ferrando_text")
    fr["color"] = np.ones((H, W, 3), F)
    step(t2, fr, (CUR, CUR))
    fr["color"] = np.zeros((H, W, 3), F)
    assert not np.any(step(t2, fr, (CUR, CUR)))


def _buffer_frame(colour, motion):
    h, w = colour.shape[:2]
    return dict(color=np.asarray(colour, F), motion=np.broadcast_to(np.asarray(motion, F), (h, w, 2)).copy())


def test_history_neighbourhood_clamp_by_hand():
    """The printed clamp: min/max over the history's 3x3 around the reprojected position (bilinear
    taps at +-1 pixel), then clamp the history sample -- which is one of the 9 taps, so nothing moves."""
    hist = np.array([[0.0, 0.1, 0.9, 0.2],
                     [0.5, 0.7, 0.3, 0.4],
                     [0.8, 0.6, 1.0, 0.05]], F)
    hist3 = np.repeat(hist[..., None], 3, -1)
    cur = np.full_like(hist3, 0.2)
    for clamp in ("history", "current", "none"):
        t = taa_impl.make("taa_ferrando_code", clamp=clamp, motion_source="buffer")
        t.process(_buffer_frame(hist3, (0, 0)), jitter=(0, 0), far=FAR)   # history := hist
        out = t.process(_buffer_frame(cur, (1.0, 0.0)), jitter=(0, 0), far=FAR)  # came from x - 1
        terms = t.debug_terms()
        # pixel (x=2, y=1) reads the history at (1, 1) = 0.7
        assert terms["history_raw"][1, 2, 0] == pytest.approx(0.7)
        if clamp == "history":
            # 3x3 of the history around (1, 1): rows 0..2, columns 0..2
            assert terms["clamp_min"][1, 2, 0] == pytest.approx(0.0)
            assert terms["clamp_max"][1, 2, 0] == pytest.approx(1.0)
            # at pixel (3, 0): around (2, 0), clamp-to-edge rows 0,0,1 and columns 1..3
            assert terms["clamp_min"][0, 3, 0] == pytest.approx(0.1)
            assert terms["clamp_max"][0, 3, 0] == pytest.approx(0.9)
            np.testing.assert_allclose(out[1, 2], 0.2 * 0.4 + 0.7 * 0.6, atol=1e-7)   # unclamped
            hist_out = out
        elif clamp == "current":
            np.testing.assert_allclose(out[1, 2], 0.2, atol=1e-7)   # box of a flat 0.2 frame
            assert terms["clamp_min"][1, 2, 0] == terms["clamp_max"][1, 2, 0] == pytest.approx(0.2)
        else:
            np.testing.assert_array_equal(out, hist_out)   # the printed clamp is a no-op ...
    # ... for fractional motion too
    rng = np.random.default_rng(3)
    frames = [rng.uniform(0, 2, (7, 9, 3)).astype(F) for _ in range(4)]
    motions = [(0.0, 0.0), (0.37, -0.61), (-1.25, 0.5), (2.5, 1.75)]
    a = taa_impl.make("taa_ferrando_code", motion_source="buffer")
    b = taa_impl.make("taa_ferrando_code", motion_source="buffer", clamp="none")
    for fr, mv in zip(frames, motions):
        np.testing.assert_array_equal(a.process(_buffer_frame(fr, mv), jitter=(0, 0), far=FAR),
                                      b.process(_buffer_frame(fr, mv), jitter=(0, 0), far=FAR))


def test_offscreen_and_errors():
    t = taa_impl.make("taa_ferrando_text")
    fr = frame_for(CUR)
    with pytest.raises(ValueError, match="cameras"):
        t.process(fr, jitter=(0, 0), far=FAR)
    with pytest.raises(ValueError, match="camera is"):
        step(t, fr, (cam((0, 0, 5), (0, 0, 0), w=10, h=10), CUR))
    with pytest.raises(TypeError):
        step(t, fr, (CUR, "not a camera"))
    # off-screen: 'reject' takes the current colour, 'edge' reads the clamped border texel
    c0 = np.full((3, 4, 3), 1.0, F)
    c1 = np.zeros((3, 4, 3), F)
    for mode, expect in (("reject", 0.0), ("edge", 0.3)):
        t = taa_impl.make("taa_ferrando_code_noclamp", motion_source="buffer", offscreen=mode)
        t.process(_buffer_frame(c0, (0, 0)), jitter=(0, 0), far=FAR)
        out = t.process(_buffer_frame(c1, (40.0, 0.0)), jitter=(0, 0), far=FAR)
        np.testing.assert_allclose(out, expect, atol=1e-7)


def test_depth_motion_matches_the_raster_motion_buffer_for_a_still_scene():
    """End to end: on a static scene seen by a moving camera, the motion reconstructed from the
    raster's depth and the two cameras equals the raster's own motion buffer."""
    from raster import Rasterizer
    from scenes.jitter import halton_offset
    from tests.conftest import two_colour_scene
    scene = two_colour_scene(velocity=(0.05, 0.02, 0.0), target_velocity=(0.05, 0.02, 0.0))
    w, h = 40, 30
    r = Rasterizer(scene, w, h)
    try:
        for t in (1, 4):
            fr = r.render(t, halton_offset(t), ("depth", "motion"))
            m = motion_from_depth(fr["depth"], scene.camera(t, w, h), scene.camera(t - 1, w, h))
            assert np.abs(fr["motion"]).max() > 0.3
            np.testing.assert_allclose(m, fr["motion"], atol=1e-3)
    finally:
        r.close()
