import numpy as np
import pytest

from backend import dr, mi
from conftest import quad_object, two_colour_scene
from raster import BUFFERS, Rasterizer
from raster.visibility import RasterError
from references.mitsuba_scene import sensor
from scenes.description import Camera, Material, MeshSpec, Motion, Scene, SceneObject, Transform
from scenes.resolved import ResolvedScene
from shading import frame_geometry, trace_visible

W, H = 64, 48


@pytest.fixture(scope="module")
def edge_raster():
    """A backdrop and a large quad whose left edge is vertical at image x = 30.37 and whose top
    edge is horizontal at image y = 20.62 (y down)."""
    base = two_colour_scene()
    cam = base.camera(0, W, H)
    tx, ty = cam.tan_half
    d = 5.0 - 0.5                         # the quad sits at z = 0.5, the eye at z = 5
    ex = (2 * 30.37 / W - 1) * tx * d
    ey = (1 - 2 * 20.62 / H) * ty * d
    size = 10.0
    front = quad_object("front", (size, size), (ex + size / 2, ey - size / 2, 0.5), (1.0, 0.0, 0.0))
    scene = ResolvedScene(base.desc.model_copy(update={"objects": (front, base.desc.objects[1])}))
    r = Rasterizer(scene, W, H)
    yield r
    r.close()


def test_single_sample_edge_has_only_the_two_pure_colours():
    r = Rasterizer(two_colour_scene(rotate_deg=17.0), W, H)
    try:
        col = r.render(0, (0.13, -0.21), ("color",))["color"]
        assert r.samples_per_pixel == 1
    finally:
        r.close()
    colours = {tuple(c) for c in col.reshape(-1, 3).tolist()}
    assert colours == {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)}


@pytest.mark.parametrize("ox", [-0.45, -0.3, -0.2, -0.05, 0.1, 0.25, 0.4])
def test_vertical_edge_moves_by_exactly_the_x_offset(edge_raster, ox):
    ids = edge_raster.render(0, (ox, 0.0), ("object_id",))["object_id"]
    row = ids[H - 2]                                   # below the top edge
    first = int(np.argmax(row == 1))
    assert first == int(np.floor(30.37 - 0.5 - ox)) + 1
    assert np.all(row[first:] == 1) and np.all(row[:first] == 2)


@pytest.mark.parametrize("oy", [-0.45, -0.2, 0.05, 0.3, 0.45])
def test_horizontal_edge_moves_by_exactly_the_y_offset(edge_raster, oy):
    ids = edge_raster.render(0, (0.0, oy), ("object_id",))["object_id"]
    col = ids[:, W - 2]
    first = int(np.argmax(col == 1))                   # first covered row from the top
    assert first == int(np.floor(20.62 - 0.5 - oy)) + 1


def test_depth_is_the_exact_depth_at_the_jittered_sample():
    cam_desc = Camera(position=(0, 0, 5), target=(0, 0, 0), yfov_deg=30, near=0.5, far=50)
    plane = SceneObject(name="tilted", mesh=MeshSpec(kind="plane", size=(30, 30, 0)),
                        transform=Transform(rotate_axis=(0, 1, 0), rotate_deg=40))
    scene = ResolvedScene(Scene(name="tilt", transport="unlit", camera=cam_desc, objects=(plane,)))
    r = Rasterizer(scene, W, H)
    try:
        jit = (0.31, -0.17)
        out = r.render(0, jit, ("depth", "motion", "prev_depth"))
    finally:
        r.close()
    assert set(out) == {"depth", "motion", "prev_depth"}           # only what was asked for
    cam = scene.camera(0, W, H)
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    d = cam.ray_directions(xs.ravel() + jit[0], ys.ravel() + jit[1])
    n = np.array([np.sin(np.radians(40)), 0, np.cos(np.radians(40))])
    t = -(cam.position @ n) / (d @ n)                               # plane through the origin
    np.testing.assert_allclose(out["depth"].ravel(), t, rtol=2e-6)
    assert np.all(out["motion"] == 0) and np.array_equal(out["prev_depth"], out["depth"])


def _mitsuba_hit(scene, t, positions):
    """World point and object id Mitsuba sees through image positions (N, 2) at frame t."""
    cam = scene.camera(t, W, H)
    geo = frame_geometry(scene, t)
    pos = mi.Point2f(mi.Float(positions[:, 0] / W), mi.Float(positions[:, 1] / H))
    ray, _ = sensor(cam, 1).sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    surf, _ = trace_visible(geo, mi.Ray3f(ray))
    return np.array([np.asarray(surf.p[k]) for k in range(3)]).T, np.asarray(surf.obj)


def _moving_scene(motion=Motion(), cam_velocity=(0, 0, 0), target_velocity=(0, 0, 0)):
    cam = Camera(position=(0.5, 0.4, 4), target=(0, 0, 0), yfov_deg=40, near=0.5, far=50,
                 velocity=cam_velocity, target_velocity=target_velocity)
    ball = SceneObject(name="ball", mesh=MeshSpec(kind="sphere", radius=0.8, segments=24, smooth=True),
                       material=Material(albedo=(0.9, 0.5, 0.1)), transform=Transform(translate=(0, 0, 0)),
                       motion=motion)
    wall = SceneObject(name="wall", mesh=MeshSpec(kind="box", size=(12, 8, 0.2)),
                       transform=Transform(translate=(0, 0, -2)))
    return ResolvedScene(Scene(name="moving", transport="unlit", camera=cam, objects=(ball, wall), frames=8))


@pytest.mark.parametrize("case", ["translating", "rotating", "camera"])
def test_motion_vectors_land_on_the_same_surface_point(case):
    scene = {
        "translating": lambda: _moving_scene(Motion(velocity=(0.07, -0.03, 0.05))),
        "rotating": lambda: _moving_scene(Motion(spin_axis=(0.3, 1, 0.2), spin_deg=9.0)),
        "camera": lambda: _moving_scene(cam_velocity=(0.08, 0.03, -0.05), target_velocity=(0.02, 0, 0)),
    }[case]()
    t = 4
    r = Rasterizer(scene, W, H)
    try:
        b = r.render(t, (0.0, 0.0), ("object_id", "motion", "depth", "prev_depth"))
    finally:
        r.close()
    assert np.abs(b["motion"]).max() > 0.5                    # something really moves
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    cam = scene.camera(t, W, H)
    p_now = cam.position + cam.ray_directions(xs.ravel(), ys.ravel()) * b["depth"].ravel()[:, None]
    obj = b["object_id"].ravel()
    # The same material point one frame earlier, through the object's own poses.
    p_prev = np.empty_like(p_now)
    for i in range(2):
        sel = obj == i + 1
        m_now, m_prev = scene.object_pose(i, t), scene.object_pose(i, t - 1)
        local = (p_now[sel] - m_now[:3, 3]) @ np.linalg.inv(m_now[:3, :3]).T
        p_prev[sel] = local @ m_prev[:3, :3].T + m_prev[:3, 3]
    prev_pos = np.stack([xs.ravel(), ys.ravel()], -1) - b["motion"].reshape(-1, 2)
    hit_p, hit_obj = _mitsuba_hit(scene, t - 1, prev_pos)
    inside = (prev_pos[:, 0] > 1) & (prev_pos[:, 0] < W - 1) & (prev_pos[:, 1] > 1) & (prev_pos[:, 1] < H - 1)
    prev_cam = scene.camera(t - 1, W, H)
    _, hit_depth = prev_cam.project(hit_p)
    _, want_depth = prev_cam.project(p_prev)
    # A disocclusion: the point was hidden, so the previous frame saw something nearer. Everywhere
    # else the previous frame must see the very same point (a wrong vector lands nearer or farther).
    hidden = inside & (hit_depth < want_depth - 1e-3)
    assert hidden.mean() < 0.03
    ok = inside & ~hidden
    # A point exactly on the previous frame's silhouette may graze past it: allowed only where a
    # ray 0.05 px away does see the expected object.
    grazing = np.nonzero(ok & (hit_obj != obj))[0]
    assert len(grazing) <= 0.002 * ok.sum()
    for k in grazing:
        near = prev_pos[k] + np.array([[0.05, 0.05], [-0.05, 0.05], [0.05, -0.05], [-0.05, -0.05]])
        assert obj[k] in _mitsuba_hit(scene, t - 1, near)[1]
    ok[grazing] = False
    np.testing.assert_allclose(hit_p[ok], p_prev[ok], atol=2e-4)
    # And prev_depth is that point's depth in the previous camera.
    _, dprev = scene.camera(t - 1, W, H).project(p_prev[ok])
    np.testing.assert_allclose(b["prev_depth"].ravel()[ok], dprev, rtol=1e-4)


def test_unknown_buffer_is_refused():
    r = Rasterizer(two_colour_scene(), 16, 16)
    try:
        with pytest.raises(RasterError, match="unknown buffer"):
            r.render(0, (0, 0), ("colour",))
        out = r.render(0, (0, 0), BUFFERS)
        assert set(out) == set(BUFFERS)
        assert out["object_id"].dtype == np.int32 and out["color"].dtype == np.float32
    finally:
        r.close()


def test_supersample_shades_only_masked_pixels_and_equals_the_mean_of_full_frames():
    from scenes import get_scene
    from scenes.jitter import halton_offsets
    scene = get_scene("atrium")
    r = Rasterizer(scene, 40, 24)
    try:
        mask = np.zeros((24, 40), bool)
        mask[5:12, 10:30] = True
        offs = halton_offsets(8)
        ss, stats = r.supersample(0, mask, offs)
        full = np.mean([r.render(0, o, ("color",))["color"] for o in offs], axis=0)
    finally:
        r.close()
    np.testing.assert_allclose(ss[mask], full[mask], atol=1e-6)
    assert np.all(ss[~mask] == 0)
    assert stats["samples_shaded"] == mask.sum() * 8 and stats["pixels_supersampled"] == mask.sum()
    assert 0 < stats["objects_needed"] <= stats["objects_total"]


def test_supersample_reuses_a_scene_time_s_samples_bit_for_bit_and_forgets_them_at_another_time():
    """A static test asks one time's extra samples 256 times over overlapping masks: pixels shaded
    before are not shaded again, and the image and counts are a fresh rasterizer's."""
    import raster.frames as F
    from scenes.jitter import halton_offsets
    scene = _moving_scene(Motion(velocity=(0.07, -0.03, 0.05)), cam_velocity=(0.05, 0, 0))
    offs = halton_offsets(4)
    m0, m1 = np.zeros((H, W), bool), np.zeros((H, W), bool)
    m0[2:9, 3:20] = True
    m1[5:14, 10:28] = True                   # overlaps m0
    every = np.ones((H, W), bool)
    n = lambda m: 4 * int(m.sum())           # noqa: E731  samples of 4 offsets
    calls = [(3, m0, n(m0)), (3, m1, n(m1 & ~m0)), (3, every, n(~(m0 | m1))),
             (5, m0, n(m0)),                 # another time: all again
             (3, m0, n(m0))]                 # and time 3's were forgotten
    r, fresh = Rasterizer(scene, W, H), Rasterizer(scene, W, H)
    shaded, real = [], F.shade

    def counting(geo, surf, *a):
        shaded.append(dr.width(surf.obj))
        return real(geo, surf, *a)
    try:
        F.shade = counting
        for t, m, want_shaded in calls:
            shaded.clear()
            got, stats = r.supersample(t, m, offs)
            assert sum(shaded) == want_shaded, (t, sum(shaded), want_shaded)
            want, want_stats = fresh.supersample(t, m, offs, reuse=False)
            assert np.array_equal(got, want) and stats == want_stats
            assert np.any(got[m] != 0)
    finally:
        F.shade = real
        r.close()
        fresh.close()


def test_motion_refers_to_the_given_previous_time():
    """A static test renders many frames of one instant: with prev_t = t nothing moves."""
    scene = _moving_scene(Motion(velocity=(0.07, -0.03, 0.05)), cam_velocity=(0.05, 0, 0))
    r = Rasterizer(scene, W, H)
    try:
        still = r.render(4, (0.2, 0.1), ("motion", "depth", "prev_depth"), prev_t=4)
        moving = r.render(4, (0.2, 0.1), ("motion",))
    finally:
        r.close()
    assert np.abs(still["motion"]).max() < 1e-4 and np.allclose(still["prev_depth"], still["depth"], rtol=1e-6)
    assert np.abs(moving["motion"]).max() > 0.5


def test_a_moving_camera_and_new_jitter_compile_no_new_kernel():
    """Frames differ in camera pose, jitter and light-independent values only: once the first
    frames have compiled the kernels, later frames reuse them (each was compiled again per frame
    while the camera, jitter, eye and lights were literals in the kernel: 6 kernels, ~150 ms a
    frame at 320x180, paid again on every new machine)."""
    from scenes.jitter import halton_offset
    base = two_colour_scene(transport="direct", velocity=(0.02, 0.01, 0.0))
    scene = ResolvedScene(base.desc.model_copy(update={"frames": 8}))
    r = Rasterizer(scene, 32, 24)
    try:
        for t in range(3):
            r.render(t, jitter=halton_offset(t), buffers=("color", "depth", "motion"), prev_t=max(t - 1, 0))
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history_clear()
        for t in range(3, 6):
            r.render(t, jitter=halton_offset(t), buffers=("color", "depth", "motion"), prev_t=t - 1)
        hist = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        r.close()
    jit = [k for k in hist if k["type"] == dr.KernelType.JIT]
    # reused from this process's memory: neither compiled nor loaded from the disk cache (which
    # holds a new kernel once any earlier process compiled it)
    new = [k["hash"] for k in jit if not k["cache_hit"] or k["cache_disk"]]
    assert jit and not new, new


def test_every_buffer_of_a_frame_is_one_kernel_launch_and_the_same_as_asked_alone():
    """A frame's float buffers are evaluated together: converting colour channel by channel
    launched the whole shading once per channel and depth, motion and normal once more each
    (6 launches a TAA frame, 14 for every buffer; 1.2-1.7x the raster's frame time at 320x180).
    Evaluated together, each buffer is bit for bit what it is when asked for alone."""
    from scenes.jitter import halton_offset
    scene = two_colour_scene(transport="direct", velocity=(0.02, 0.01, 0.0))
    scene = ResolvedScene(scene.desc.model_copy(update={"frames": 4}))
    every = BUFFERS
    r = Rasterizer(scene, 32, 24)
    try:
        r.render(1, halton_offset(1), every, prev_t=0)             # compiles
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history_clear()
        together = r.render(1, halton_offset(2), every, prev_t=0)
        hist = dr.kernel_history()
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        alone = {b: r.render(1, halton_offset(2), (b,), prev_t=0)[b] for b in every}
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        r.close()
    jit = [k for k in hist if k["type"] == dr.KernelType.JIT]
    assert len(jit) == 1, [k["hash"] for k in jit]
    assert set(together) == set(every)
    for b in every:
        assert together[b].dtype == alone[b].dtype and np.array_equal(together[b], alone[b]), b
