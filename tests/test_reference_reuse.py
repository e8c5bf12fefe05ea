"""Reference reuse across frames (references.reuse, references.render's `reuse_from`): a still
camera, one moving sphere and its shadow; the pixels kept from the previous frame are those no
moving object nor shadow reaches, and they are still estimates of this frame's reference."""
import json
import numpy as np
import pytest

from references import ReferenceCache, render_reference
from references.estimates import dilate
from references.reuse import changed_pixels, reuse_mask
from scenes.description import (Camera, DirectionalLight, Material, MeshSpec, Motion, PointLight, Scene,
                                SceneObject, Texture, Transform)
from scenes.resolved import ResolvedScene

W, H = 48, 27
FAST = dict(se_bound_lsb=4.0, target_noise_db=0.0, held_out=True)


def probe(light: str = "directional", transport: str = "direct_shadows", camera_velocity=(0.0, 0.0, 0.0),
          spin: float = 0.0) -> ResolvedScene:
    """A floor, a static box, and a sphere moving along x above the floor (spinning with `spin`)."""
    lights = {"directional": (DirectionalLight(direction=(0.4, -1.0, -0.3), intensity=(1.5, 1.5, 1.4)),),
              "point": (PointLight(position=(0.3, 1.4, 0.6), intensity=(1.6, 1.5, 1.4)),)}[light]
    objects = (
        SceneObject(name="floor", mesh=MeshSpec(kind="box", size=(4.0, 0.1, 3.0)),
                    material=Material(albedo=(0.6, 0.6, 0.6), texture=Texture(kind="checker", squares=24)),
                    transform=Transform(translate=(0.0, -0.05, 0.0))),
        SceneObject(name="block", mesh=MeshSpec(kind="box", size=(0.3, 0.5, 0.3)),
                    material=Material(albedo=(0.2, 0.4, 0.8)), transform=Transform(translate=(0.7, 0.25, -0.4))),
        SceneObject(name="ball", mesh=MeshSpec(kind="sphere", radius=0.22, segments=24),
                    material=Material(albedo=(0.9, 0.35, 0.1)), transform=Transform(translate=(-0.7, 0.45, 0.2)),
                    motion=Motion(velocity=(0.12, 0.0, 0.0), spin_axis=(0, 0, 1), spin_deg=spin)))
    return ResolvedScene(Scene(
        name="reuse_probe", transport=transport, frames=6, objects=objects, lights=lights,
        camera=Camera(position=(0.0, 1.3, 2.4), target=(0.0, 0.2, 0.0), yfov_deg=45, far=20,
                      velocity=camera_velocity),
        ambient=(0.12, 0.12, 0.14), background=(0.2, 0.25, 0.3)))


def crossed(scene: ResolvedScene, t: int, w: int, h: int, shadows: bool = True) -> np.ndarray:
    """Brute force: the pixels whose square holds a point of the moving sphere's surface, or of
    its shadow on the floor, at any of 17 times in [t - 1, t] (points drawn on its triangles)."""
    i = [o.name for o in scene.desc.objects].index("ball")
    mesh = scene.meshes[i]
    rng = np.random.default_rng(1)
    tri = mesh.vertices[mesh.faces]                                  # (F, 3, 3)
    f = rng.integers(len(tri), size=6000)
    u, v = rng.random((2, len(f)))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    local = tri[f, 0] + u[:, None] * (tri[f, 1] - tri[f, 0]) + v[:, None] * (tri[f, 2] - tri[f, 0])
    local = np.concatenate([local, mesh.vertices])
    cam = scene.camera(t, w, h)
    out = np.zeros((h, w), bool)
    light = scene.desc.lights[0]
    for s in np.linspace(t - 1, t, 17):
        pose = scene.object_pose(i, s)
        p = local @ pose[:3, :3].T + pose[:3, 3]
        pts = [p]
        if shadows:
            d = (p - np.asarray(light.position)) if light.type == "point" else np.broadcast_to(light.direction, p.shape)
            k = -p[:, 1] / d[:, 1]                                    # to the floor's top, y = 0
            q = p + k[:, None] * d
            on = (k > 0) & (np.abs(q[:, 0]) <= 2.0) & (np.abs(q[:, 2]) <= 1.5)
            pts.append(q[on])
        for q in pts:
            xy, depth = cam.project(q)
            x, y = np.floor(xy[:, 0]).astype(int), np.floor(xy[:, 1]).astype(int)
            ok = (depth > 0) & (x >= 0) & (x < w) & (y >= 0) & (y < h)
            out[y[ok], x[ok]] = True
    return out


@pytest.mark.parametrize("light", ["directional", "point"])
@pytest.mark.parametrize("spin", [0.0, 25.0])
def test_no_pixel_the_sphere_or_its_shadow_crosses_is_reused(light, spin):
    scene = probe(light, spin=spin)
    w, h = 96, 54
    for t in (1, 5):
        hit = crossed(scene, t, w, h)
        keep = reuse_mask(scene, t, w, h)
        assert hit.sum() > 100 and crossed(scene, t, w, h, shadows=False).sum() < hit.sum()
        # nothing crossed is kept, nor has a crossed pixel in its 3x3 window (the floor reads it)
        assert not (keep & dilate(hit)).any(), (light, spin, t, int((keep & dilate(hit)).sum()))
        # and the test is conservative, not everything: most of the frame is kept
        assert keep.mean() > 0.5, keep.mean()


def test_the_bound_is_whole_pixels_before_the_margin():
    # undilated, the swept boxes still hold every crossed pixel: the margin is for the floor's window
    scene = probe("point")
    w, h = 96, 54
    for t in (1, 4):
        assert not (crossed(scene, t, w, h) & ~changed_pixels(scene, t, w, h, dilate=False)).any()


def test_a_moving_camera_or_a_cut_or_path_transport_reuses_nothing(tmp_path):
    moving = probe(camera_velocity=(0.02, 0.0, 0.0))
    assert reuse_mask(moving, 2, W, H) is None
    prev = render_reference(moving, 1, W, H, **FAST)
    ref = render_reference(moving, 2, W, H, reuse_from=prev, **FAST)
    assert ref.reused is None and ref.traced == ref.spp_map.sum()
    # its cache key is the plain one: nothing was derived from frame 1
    cache = ReferenceCache(tmp_path)
    assert cache.key(moving, 2, W, H, reuse=True, **FAST) == cache.key(moving, 2, W, H, **FAST)
    assert reuse_mask(probe(), 0, W, H) is None                                 # the first frame
    assert reuse_mask(probe(transport="path"), 2, W, H) is None                  # indirect light
    assert reuse_mask(probe(transport="direct"), 2, W, H).mean() > 0.5


def test_reused_pixels_are_estimates_of_the_frame_and_their_halves_stay_independent():
    scene = probe()
    prev = render_reference(scene, 2, W, H, **FAST)
    ref = render_reference(scene, 3, W, H, reuse_from=prev, **FAST)
    fresh = render_reference(scene, 3, W, H, seed=11, **FAST)
    kept = ref.reused
    assert kept.mean() > 0.4 and ref.traced < 0.8 * fresh.traced, (kept.mean(), ref.traced / fresh.traced)
    assert np.array_equal(ref.image[kept], prev.image[kept])
    assert np.array_equal(ref.spp_map[kept], prev.spp_map[kept])
    # a kept pixel agrees with a fresh render of this frame within their standard errors
    se = np.sqrt(ref.stderr.astype(np.float64) ** 2 + fresh.stderr ** 2)
    diff = np.abs(ref.image.astype(np.float64) - fresh.image)
    z = np.divide(diff, se, out=np.where(diff > 1e-6, np.inf, 0.0), where=se > 0)[kept]
    assert np.mean(z < 4) >= 0.999, np.sort(z.ravel())[-5:]
    # the moving sphere's own pixels do differ from the previous frame's: the test can see a change
    moved = ~dilate(~changed_pixels(scene, 3, W, H, dilate=False))
    zp = (np.abs(prev.image.astype(np.float64) - fresh.image) /
          np.maximum(np.sqrt(prev.stderr.astype(np.float64) ** 2 + fresh.stderr ** 2), 1e-9))[moved]
    assert np.mean(zp > 4) > 0.05
    # the halves of a kept pixel are still two independent estimates: (A - B) / 2 over its SE
    # (where the spread, not the unseen-feature floor, is its SE) has mean ~0 and variance ~1
    a, b = ref.halves()
    g = 1                                          # one channel: the three move together
    spread = (ref.display_floor[..., g] < ref.display_stderr[..., g]) & (ref.stderr[..., g] > 0) & kept
    zh = ((a - b)[..., g] / 2 / np.where(spread, ref.stderr[..., g], 1))[spread]
    assert len(zh) > 150, len(zh)
    assert abs(zh.mean()) < 4 / np.sqrt(len(zh)) and 0.6 < zh.var() < 1.6, (zh.mean(), zh.var())


def test_a_reused_frames_key_hashes_the_frame_it_derives_from(tmp_path):
    scene = probe()
    cache = ReferenceCache(tmp_path)
    plain = cache.key(scene, 3, W, H, **FAST)
    chained = cache.key(scene, 3, W, H, reuse=True, **FAST)
    assert chained != plain
    # a chain that starts later derives from other references: another key
    assert cache.key(scene, 3, W, H, reuse=True, reuse_since=1, **FAST) != chained
    assert cache.key(scene, 3, W, H, reuse=True, reuse_since=3, **FAST) == plain    # rendered whole
    assert cache.key(scene, 0, W, H, reuse=True, **FAST) == cache.key(scene, 0, W, H, **FAST)
    # the settings of the frame it derives from are in the key: another bound, another chain
    assert cache.key(scene, 3, W, H, reuse=True, **{**FAST, "se_bound_lsb": 2.0}) != chained
    ref, cached = cache.get(scene, 2, W, H, reuse=True, reuse_since=1, **FAST)
    assert not cached and ref.reused is not None and ref.reused.any()
    again, cached = cache.get(scene, 2, W, H, reuse=True, reuse_since=1, **FAST)
    assert cached and np.array_equal(again.reused, ref.reused) and np.array_equal(again.sample_lo, ref.sample_lo)
    # the chain's first frame was rendered whole and filed under the plain key
    assert cache.has(scene, 1, W, H, **FAST) and not cache.has(scene, 2, W, H, **FAST)
    assert cache.has(scene, 2, W, H, reuse=True, reuse_since=1, **FAST)
    assert not cache.has(scene, 2, W, H, reuse=True, reuse_since=0, **FAST)
    # frame 1's extremes made frame 2 and went (nothing else reads them); frame 2's, the chain's
    # end, stay beside it for frame 3
    from references.cache import extremes_path
    first = cache.path(scene, cache.settings_key(scene, 1, W, H, **FAST))
    last = cache.path(scene, cache.settings_key(scene, 2, W, H, reuse=True, reuse_since=1, **FAST))
    assert first.exists() and not extremes_path(first).exists() and extremes_path(last).exists()
    assert cache.get(scene, 1, W, H, reuse=True, reuse_since=1, **FAST)[0].sample_lo is None


def test_a_ghosting_tests_references_chain_over_runs_of_frames_at_one_setting(tmp_path):
    """The planner: with `reuse`, frame t's reference task runs after frame t - 1's (at the same
    settings); an instant the precision rule refines alone starts its own chain; without, none."""
    from study.config.protocols import Protocol
    from study.config.techniques import TechniqueConfig
    from study.engine.plan import Planner
    from study.engine.reuse_chain import chain_reuse
    from study.engine.tasks import Context, load_scene
    scene = load_scene("sphere_ghosting")
    proto = Protocol("ghosting", "ghosting", frames=5)
    fx = [TechniqueConfig.parse("FXAA=fxaa")]
    base = {**FAST, "reuse": True}
    finer = {**base, "se_bound_lsb": 1.0}
    pl = Planner(Context(str(tmp_path), 1), base, None, {("sphere_ghosting", "ghosting", 3): finer}, base)
    test = pl.add_test("sphere_ghosting", scene, proto, fx, 32, 18)
    at = test.ref_settings_at
    # frame 3, refined alone, starts a chain; frame 4 chains through frame 3's display reference
    # (planned at every frame anyway): nothing is rendered only to be reused
    assert at[0] == at[1] == at[2] == at[4] == base and at[3] == {**finer, "reuse_since": 3}
    deps = {t: pl.plan.tasks[test.reference_tasks[t]].deps for t in at}
    assert deps[0] == deps[3] == ()
    for t in (1, 2, 4):
        assert deps[t] == (pl.reference_key(scene, t - 1, 32, 18, base),)
    # at settings of their own, frames 3 and 4 chain; frame 5 at the display's starts after them
    at = chain_reuse({t: finer if t in (3, 4) else base for t in range(6)}, ({**FAST, "reuse": True},))
    assert at[3] == at[4] == {**finer, "reuse_since": 3} and at[5] == base
    at = chain_reuse({t: finer if t in (3, 4) else base for t in range(6)}, (FAST,))
    assert at[2] == base and at[5] == {**base, "reuse_since": 5}
    # the test's own settings chain over the whole run, through the instants refined alone: their
    # refinement re-keys no other instant (frame 5 reuses frame 4's reference at the test's own)
    at = chain_reuse({t: finer if t in (3, 4) else base for t in range(6)}, (FAST, base))
    assert at[2] == at[5] == base and at[3] == at[4] == {**finer, "reuse_since": 3}
    off = Planner(Context(str(tmp_path), 1), FAST, None, {}, FAST)
    t_off = off.add_test("sphere_ghosting", scene, proto, fx, 32, 18)
    assert all(off.plan.tasks[k].deps == () for k in t_off.reference_tasks.values())


def test_the_spinning_objects_polyhedron_holds_its_bounding_sphere():
    from scipy.spatial import ConvexHull

    from references.reuse import _circumscribed
    pts = _circumscribed()
    eq = ConvexHull(pts).equations                       # n.x + d <= 0 inside
    assert (-eq[:, 3]).min() >= 1.0                      # every facet plane at least the radius away
    u = np.random.default_rng(0).normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    assert (u @ eq[:, :3].T + eq[:, 3]).max() <= 0
    assert np.linalg.norm(pts, axis=1).max() < 1.1       # and not much more than it


def test_the_study_reads_an_instants_reference_with_the_settings_its_plan_rendered_it_with(tmp_path, monkeypatch):
    """The report reaches a reference through Study.reference: it must ask the cache with the
    settings the plan rendered that instant with. An instant refined alone starts a chain of its
    own (`reuse_since`); asked without it, the cache finds nothing and renders the chain again
    from frame 0 (the report of a quick study once re-rendered its ghosting references so)."""
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    from study.engine.tasks import load_scene
    s = Study("quick", cache_root=tmp_path, progress=False)
    s.ref_settings["reuse"] = True
    from study.engine.rounds import InstantKey
    s.levels[InstantKey("sphere_ghosting", "ghosting", 3)] = 2
    ghosts = s.plan(["sphere_ghosting"], [TechniqueConfig.parse("FXAA=fxaa")], agreement=False)[3]
    asked = []
    monkeypatch.setattr(s.cache, "get", lambda scene, t, w, h, **kw: (asked.append((t, kw)) or (None, True)))
    test = next(g for g in ghosts if g.protocol.name == "ghosting")
    scene = load_scene("sphere_ghosting")
    for t in sorted(test.ref_settings_at):
        s.reference(scene, t, test.width, test.height, "ghosting")
    assert asked == [(t, test.ref_settings_at[t]) for t in sorted(test.ref_settings_at)]
    assert any(kw.get("reuse_since") == 3 for _, kw in asked)
    asked.clear()
    s.reference(scene, 500, test.width, test.height, "ghosting")      # judged by no test: rendered whole
    assert "reuse" not in asked[0][1] and "reuse_since" not in asked[0][1]


def test_reuse_named_by_scene_is_on_for_those_scenes_only(tmp_path):
    """`[reference] reuse` as a list of scene names (the thesis profile: sphere_ghosting alone): a
    scene it names chains its frames; another renders each frame whole and keeps no extremes."""
    from references.cache import extremes_path, reuse_on
    assert reuse_on("a", True) and reuse_on("a", ("a", "b")) and not reuse_on("c", ("a", "b"))
    assert not reuse_on("a", False) and not reuse_on("a", ())
    scene, cache = probe(), ReferenceCache(tmp_path)
    on, off = ("reuse_probe",), ("sphere_ghosting",)
    ref, _ = cache.get(scene, 2, W, H, reuse=on, reuse_since=1, **FAST)
    assert ref.reused is not None and ref.reused.any()
    ref, _ = cache.get(scene, 2, W, H, reuse=off, reuse_since=1, **FAST)
    assert ref.reused is None                    # rendered whole, and its extremes not kept:
    assert not extremes_path(cache.path(scene, cache.settings_key(scene, 2, W, H, reuse=off, reuse_since=1, **FAST))).exists()
    assert len(cache.settings_chain(scene, 2, W, H, reuse=off, reuse_since=1, **FAST)) == 1


def test_a_study_file_names_only_its_own_scenes_for_reuse(tmp_path):
    from study_fixtures import run_cli, write_scenes
    scenes = write_scenes(tmp_path)
    f = tmp_path / "s.toml"
    for reuse, words in (('["tiny_movng"]', "reference.reuse[0]"), ('"yes"', "reference.reuse")):
        f.write_text(f'name = "s"\nscenes = {json.dumps(scenes)}\n[[techniques]]\nspec = "noaa"\n'
                     f'[reference]\nreuse = {reuse}\n')
        r = run_cli(["estimate", str(f)], code=2)
        assert words in r.output and "Traceback" not in r.output, r.output
