"""The glTF 2.0 metallic-roughness model (shading/brdf.py, shading/material.py): the Dr.Jit BRDF
against an independent float64 NumPy transcription of the glTF specification's appendix B, its
directional albedo, normal mapping against geometry, bad parameters, and raster-reference agreement."""
import math

import numpy as np
import pytest
from click.testing import CliRunner

from backend import mi
from references import ReferenceCache
from scenes import SceneError
from scenes.description import (Camera, DirectionalLight, Material, MeshSpec, PointLight, Scene, SceneObject,
                                Texture, Transform)
from scenes.loader import load_scene_file
from scenes.resolved import ResolvedScene
from shading import Surface, frame_geometry, shade
from shading.brdf import MIN_ALPHA, gltf_brdf
from study.commands.cli import main


def _unit(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _np_brdf(n, v, l, base, metallic, rough):
    """Appendix B as written: D with (N.H)^2 (a^2 - 1) + 1, G as the product of two G1."""
    dot = lambda a, b: np.sum(a * b, -1, keepdims=True)   # noqa: E731
    h = _unit(l + v)
    nl, nv, nh, vh = dot(n, l), np.abs(dot(n, v)), dot(n, h), np.abs(dot(v, h))
    alpha = np.maximum(rough ** 2, MIN_ALPHA)[:, None]
    a2 = alpha ** 2
    c_diff = base * (1 - metallic[:, None])
    f0 = 0.04 * (1 - metallic[:, None]) + base * metallic[:, None]
    f = f0 + (1 - f0) * (1 - vh) ** 5
    d = a2 * (nh > 0) / (np.pi * (nh ** 2 * (a2 - 1) + 1) ** 2)
    g1 = lambda x: 2 * x / (x + np.sqrt(a2 + (1 - a2) * x ** 2))   # noqa: E731
    spec = f * d * g1(nl) * g1(nv) / (4 * nl * nv)
    return np.where(nl > 0, (1 - f) * c_diff / np.pi + spec, 0.0)


def _dr_brdf(n, v, l, base, metallic, rough):
    vec = lambda a: mi.Vector3f(*(mi.Float(a[:, k]) for k in range(3)))   # noqa: E731
    out = gltf_brdf(vec(n), vec(v), vec(l), mi.Color3f(*(mi.Float(base[:, k]) for k in range(3))),
                    mi.Float(metallic), mi.Float(rough))
    return np.stack([np.asarray(out[k], np.float64) for k in range(3)], -1)


def _hemisphere(rng, n, count, min_cos):
    d = _unit(rng.normal(size=(count, 3)))
    d = np.where(np.sum(d * n, -1, keepdims=True) < 0, -d, d)
    keep = np.sum(d * n, -1) > min_cos
    return d, keep


def test_brdf_matches_an_independent_float64_evaluation():
    rng = np.random.default_rng(3)
    k = 20000
    n = _unit(rng.normal(size=(k, 3)))
    v, kv = _hemisphere(rng, n, k, 0.05)
    l, kl = _hemisphere(rng, n, k, 0.05)
    keep = kv & kl
    rough = rng.uniform(0.0, 1.0, k)
    rough[:200] = 0.0                                   # the clamp to MIN_ALPHA
    metallic = rng.uniform(0.0, 1.0, k)
    metallic[200:400], metallic[400:600] = 0.0, 1.0
    base = rng.uniform(0.0, 1.0, (k, 3))
    # the same float32 inputs for both; the reference takes the directions as exact unit vectors
    # (1 - (N.H)^2 is 1e-7 off for a float32 "unit" N, and that is all of a sharp lobe's denominator)
    n, v, l, base, rough, metallic = (a.astype(np.float32).astype(np.float64)
                                      for a in (n, v, l, base, rough, metallic))
    got = _dr_brdf(n, v, l, base, metallic, rough)
    want = _np_brdf(_unit(n), _unit(v), _unit(l), base, metallic, rough)
    rel = (np.abs(got - want) / np.maximum(np.abs(want), 1e-30)).max(-1)
    # At a sharp lobe's peak the float32 rounding of the half vector (~2^-24) moves D by up to
    # 2^-23 / alpha relative, whatever the formula: 1.2e-4 at the MIN_ALPHA clamp. From alpha 0.01
    # (roughness 0.1) on that is below 1e-5, the bound asked of the whole model.
    alpha = np.maximum(rough ** 2, MIN_ALPHA)
    sharp = alpha < 0.01
    print(f"max relative error {rel[keep & ~sharp].max():.2e} over {(keep & ~sharp).sum()} direction pairs "
          f"(roughness >= 0.1), {rel[keep & sharp].max():.2e} over {(keep & sharp).sum()} sharper ones")
    assert rel[keep & ~sharp].max() <= 1e-5
    assert np.all(rel[keep & sharp] <= 1e-5 + 2.0 ** -23 / alpha[keep & sharp])
    assert np.ptp(want[keep]) > 100                     # sharp highlights are among them
    below = _dr_brdf(n, v, -l, base, metallic, rough)   # light under the surface
    assert np.all(below == 0)


# The specification's diffuse weight 1 - F(V.H) is an approximation that gains energy towards
# grazing views: a smooth white dielectric seen at cos 0.2 reflects 1.30 (roughness 0.1; 1.0080 at
# cos 0.6, roughness 0.25; the float64 reference agrees), docs/limitations.md. Metals (the specular
# lobe alone, at F0 = 1) at every view, and base colours up to 0.95 seen at cos >= 0.6, stay <= 1.
@pytest.mark.parametrize("metallic, base, views", [(1.0, 1.0, (1.0, 0.6, 0.2)), (0.0, 0.95, (1.0, 0.6)),
                                                   (0.5, 0.95, (1.0, 0.6))])
def test_directional_albedo_is_at_most_one(metallic, base, views):
    """Integral of f cos over the hemisphere of light directions (midpoint rule in theta and phi,
    steps of 1.5e-3 and 3e-3 rad: ten or more across the sharpest lobe tested, alpha = 0.01) for
    several view angles and roughnesses."""
    nt, nphi = 1024, 1024
    theta = (np.arange(nt) + 0.5) / nt * np.pi / 2
    phi = (np.arange(nphi) + 0.5) / nphi * np.pi          # v lies in the x-z plane: f is even in phi
    tt, pp = (a.ravel() for a in np.meshgrid(theta, phi, indexing="ij"))
    uu, s = np.cos(tt), np.sin(tt)
    l = np.stack([s * np.cos(pp), s * np.sin(pp), uu], -1)
    m = len(l)
    n = np.tile([0.0, 0.0, 1.0], (m, 1))
    weight = 2 * s * (np.pi / 2 / nt) * (np.pi / nphi)   # d omega = sin theta d theta d phi, both halves
    albedos = {}
    for rough in (0.1, 0.25, 0.5, 0.75, 1.0):
        for cos_v in views:
            v = np.tile([math.sqrt(1 - cos_v ** 2), 0.0, cos_v], (m, 1))
            f = _dr_brdf(n, v, l, np.full((m, 3), base), np.full(m, metallic), np.full(m, rough))
            albedos[rough, cos_v] = a = float((f[:, 0] * uu * weight).sum())
            assert a <= 1.0 + 1e-3, (rough, cos_v, a)   # 1e-3: the quadrature's error
    print({k: round(a, 4) for k, a in albedos.items()})
    if metallic == 1.0:   # a white metal at normal incidence loses little (single scattering only)
        assert albedos[0.1, 1.0] > 0.99 and albedos[1.0, 1.0] > 0.3


def _plane_scene(normal_map=None, rotate_axis=(0.0, 1.0, 0.0), rotate_deg=0.0, lights=True,
                 ambient=(0.1, 0.12, 0.15), transport="direct", **mat):
    mat = {"albedo": (0.8, 0.6, 0.4), "roughness": 0.35, "metallic": 0.4, **mat}
    return ResolvedScene(Scene(
        name="plane", transport=transport, camera=Camera(position=(0.3, 0.2, 3.0), target=(0.0, 0.0, 0.0)),
        objects=(SceneObject(name="p", mesh=MeshSpec(kind="plane", size=(4.0, 4.0, 1.0)),
                             material=Material(normal_map=normal_map, **mat),
                             transform=Transform(rotate_axis=rotate_axis, rotate_deg=rotate_deg)),),
        lights=(DirectionalLight(direction=(-0.4, -0.3, -1.0), intensity=(1.0, 0.9, 0.8)),
                PointLight(position=(-0.5, 0.8, 1.5), intensity=(2.0, 2.0, 2.0))) if lights else (),
        ambient=ambient))


def _shade_at(scene, points, normal, uv):
    geo = frame_geometry(scene, 0)
    k = len(points)
    vec = lambda a: [mi.Float(np.ascontiguousarray(a[:, j])) for j in range(a.shape[1])]   # noqa: E731
    nrm = np.tile(normal, (k, 1))
    surf = Surface(obj=mi.UInt32(np.ones(k, np.uint32)), p=mi.Point3f(*vec(points)), n_geo=mi.Vector3f(*vec(nrm)),
                   n_sh=mi.Vector3f(*vec(nrm)), uv=mi.Point2f(*vec(uv)), prim=mi.UInt32(np.zeros(k, np.uint32)))
    c = shade(geo, surf, scene.camera(0, 16, 9).position)
    return np.stack([np.asarray(c[j]) for j in range(3)], -1)


def test_a_constant_normal_map_shades_as_the_tilted_plane():
    tilt = _unit(np.array([0.3, -0.4, 0.8]))             # tangent space: x along u, y along v
    texel = ((tilt + 1) / 2).astype(np.float32)
    flat = _plane_scene(Texture(kind="array", data=np.tile(texel, (2, 2, 1))))
    axis = np.cross([0.0, 0.0, 1.0], tilt)
    tilted = _plane_scene(rotate_axis=tuple(axis), rotate_deg=float(np.degrees(np.arccos(tilt[2]))))
    # points on the rotation axis lie on both planes; the plane's u runs along x, v along y
    s = np.linspace(-1.0, 1.0, 9)[:, None]
    pts = s * _unit(axis)
    uv = (pts[:, :2] + 2.0) / 4.0
    a = _shade_at(flat, pts, [0.0, 0.0, 1.0], uv)
    b = _shade_at(tilted, pts, tilt, uv)
    print(f"normal-mapped vs tilted: max relative difference {np.max(np.abs(a - b) / np.abs(b)):.1e}")
    np.testing.assert_allclose(a, b, rtol=2e-6, atol=1e-7)
    untilted = _shade_at(tilted, pts, [0.0, 0.0, 1.0], uv)
    assert np.abs(untilted - a).max() > 1e-2               # the tilt changes the shading


def test_maps_act_as_gltf_defines_them():
    """Metallic-roughness: G scales roughness, B metallic; occlusion: 1 + strength (R - 1) on the
    ambient term only; emission texture: times the emission factor."""
    const = lambda *c: Texture(kind="array", data=np.tile(np.array(c, np.float32), (2, 2, 1)))   # noqa: E731
    pts = np.array([[0.1, 0.2, 0.0], [-0.7, 0.4, 0.0], [0.9, -1.1, 0.0]])
    uv = (pts[:, :2] + 2.0) / 4.0
    at = lambda scene: _shade_at(scene, pts, [0.0, 0.0, 1.0], uv)   # noqa: E731
    mapped = at(_plane_scene(roughness=0.8, metallic=1.0, metallic_roughness=const(0.9, 0.5, 0.25)))
    np.testing.assert_allclose(mapped, at(_plane_scene(roughness=0.4, metallic=0.25)), rtol=1e-6)
    assert np.abs(mapped - at(_plane_scene(roughness=0.2, metallic=0.5))).max() > 1e-3   # not swapped
    occ = {"occlusion": const(0.3, 0.9, 0.9), "occlusion_strength": 0.5}
    ambient_only = at(_plane_scene(lights=False, **occ)) / at(_plane_scene(lights=False))
    np.testing.assert_allclose(ambient_only, 1 + 0.5 * (0.3 - 1), rtol=1e-6)
    np.testing.assert_allclose(at(_plane_scene(ambient=(0.0, 0.0, 0.0), **occ)),
                               at(_plane_scene(ambient=(0.0, 0.0, 0.0))), rtol=1e-7)          # lights: untouched
    glow = {"emission": (2.0, 1.0, 0.5), "transport": "unlit", "albedo": (0.0, 0.0, 0.0)}
    np.testing.assert_allclose(at(_plane_scene(emission_texture=const(0.5, 0.25, 1.0), **glow)),
                               np.tile([1.0, 0.25, 0.5], (3, 1)), rtol=1e-7)
    # a Lambert material with an occlusion map takes the same rule
    lambert = at(_plane_scene(lights=False, roughness=None, metallic=None, **occ))
    np.testing.assert_allclose(lambert, np.tile(np.multiply((0.8, 0.6, 0.4), (0.1, 0.12, 0.15)) * 0.65, (3, 1)),
                               rtol=1e-6)


BAD = """
name = "bad"
transport = "direct"
ambient = [0.2, 0.2, 0.2]
[camera]
position = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
[[objects]]
name = "ball"
mesh = {{ kind = "sphere" }}
material = {{ albedo = [0.5, 0.5, 0.5], {field} = {value} }}
"""


@pytest.mark.parametrize("field, value", [("roughness", "1.5"), ("metallic", "-0.25"), ("roughness", "nan"),
                                          ("occlusion_strength", "2.0")])
def test_bad_roughness_or_metallic_is_refused_by_name(tmp_path, field, value):
    f = tmp_path / "bad.toml"
    f.write_text(BAD.format(field=field, value=value))
    with pytest.raises(SceneError) as err:
        load_scene_file(str(f))
    msg = str(err.value)
    assert str(f) in msg and f"objects[0].material.{field}" in msg and value in msg.lower()
    r = CliRunner().invoke(main, ["render", "--scene", str(f), "--no-reference", "--out", str(tmp_path / "out")])
    assert r.exit_code == 2 and f"material.{field}" in r.output and "Traceback" not in r.output
    assert not (tmp_path / "out").exists()


def test_path_transport_refuses_the_metallic_roughness_model():
    """Mitsuba's path tracer gets Lambert BSDFs (references/mitsuba_scene.py): a model material
    there would be rendered as something else, so the description refuses it by object name."""
    obj = SceneObject(name="shiny", mesh=MeshSpec(kind="sphere"), material=Material(roughness=0.3))
    with pytest.raises(ValueError, match=r"transport 'path'.*\['shiny'\]"):
        Scene(name="p", transport="path", camera=Camera(position=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0)),
              objects=(obj,), ambient=(0.2, 0.2, 0.2))
    Scene(name="p", transport="path", camera=Camera(position=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0)),
          objects=(obj.model_copy(update={"material": Material(metallic=0.0)}),), ambient=(0.2, 0.2, 0.2))
