"""A physically based glTF asset loads whole: base colour, metallic-roughness, normal, emissive and
occlusion textures and factors are read (no "not rendered" line for any of them), each texture as
its role's encoding, and a metallic low-roughness scene with it meets every agreement target."""
import base64
import io
import json
import warnings

import numpy as np
import pytest
from PIL import Image

from references import ReferenceCache
from scenes import SceneError, SceneWarning
from scenes.description import Camera, Material, MeshSpec, Scene, SceneObject, Texture
from scenes.resolved import ResolvedScene
from scenes.loader import load_scene_file
from study.engine.agreement import TARGETS, check_agreement

RNG = np.random.default_rng(11)
IMAGES = {
    "base": RNG.integers(120, 230, (8, 8, 3), dtype=np.uint8),
    # G: roughness 0.24 .. 0.55 of the factor, B: metallic 0.6 .. 1
    "mr": np.stack([np.zeros((8, 8)), RNG.integers(60, 140, (8, 8)), RNG.integers(153, 256, (8, 8))],
                   -1).astype(np.uint8),
    "normal": np.stack([RNG.integers(100, 156, (8, 8)), RNG.integers(100, 156, (8, 8)),
                        np.full((8, 8), 240)], -1).astype(np.uint8),
    "emissive": RNG.integers(0, 60, (8, 8, 3), dtype=np.uint8),
    "occlusion": np.repeat(RNG.integers(100, 256, (8, 8, 1)), 3, -1).astype(np.uint8),
}
ORDER = list(IMAGES)


def _png(a):
    b = io.BytesIO()
    Image.fromarray(a, "RGB").save(b, format="PNG")
    return "data:image/png;base64," + base64.b64encode(b.getvalue()).decode()


def write_pbr_gltf(path, tangent=None, normal_texel=None):
    """A 3 m x 3 m floor quad (y = 0) with normals and UVs, and one material using all five maps;
    `tangent`: a TANGENT (xyzw) for every vertex, `normal_texel`: a constant normal map."""
    images = dict(IMAGES)
    if normal_texel is not None:
        images["normal"] = np.tile(np.asarray(normal_texel, np.uint8), (8, 8, 1))
    pos = np.array([[-1.5, 0, 1.5], [1.5, 0, 1.5], [1.5, 0, -1.5], [-1.5, 0, -1.5]], np.float32)
    nrm = np.tile(np.array([0, 1, 0], np.float32), (4, 1))
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    data = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 48},
             {"buffer": 0, "byteOffset": 96, "byteLength": 32}, {"buffer": 0, "byteOffset": 128, "byteLength": 12}]
    attributes = {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}
    if tangent is not None:
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": 64})
        data += np.tile(np.asarray(tangent, np.float32), (4, 1)).tobytes()
        attributes["TANGENT"] = 4
    tex = {k: {"index": i} for i, k in enumerate(ORDER)}
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": 3, "material": 0}]}],
        "materials": [{
            "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0], "baseColorTexture": tex["base"],
                                     "metallicFactor": 1.0, "roughnessFactor": 0.6,
                                     "metallicRoughnessTexture": tex["mr"]},
            "normalTexture": {**tex["normal"], "scale": 0.7},
            "emissiveTexture": tex["emissive"], "emissiveFactor": [0.2, 0.3, 0.4],
            "occlusionTexture": {**tex["occlusion"], "strength": 0.8},
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}}],
        "textures": [{"source": i} for i in range(len(ORDER))],
        "images": [{"uri": _png(images[k])} for k in ORDER],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-1.5, 0, -1.5], "max": [1.5, 0, 1.5]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 4, "componentType": 5126, "count": 4, "type": "VEC4"}][:4 + (tangent is not None)],
        "bufferViews": views,
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode()}],
    }
    path.write_text(json.dumps(doc))


SCENE = """
name = "pbr_gltf"
transport = "direct_shadows"
ambient = [0.25, 0.25, 0.3]
background = [0.3, 0.35, 0.4]
[camera]
position = [0.0, 1.3, 2.6]
target = [0.0, 0.2, 0.0]
yfov_deg = 50
[[objects]]
name = "floor"
mesh = { kind = "gltf", path = "pbr.gltf" }
[[objects]]
name = "ball"
mesh = { kind = "sphere", radius = 0.45, segments = 48, smooth = true }
material = { albedo = [0.95, 0.7, 0.4], metallic = 1.0, roughness = 0.25 }
transform = { translate = [0.3, 0.45, 0.0] }
[[lights]]
type = "point"
position = [-1.0, 2.0, 1.5]
intensity = [2.0, 2.0, 2.0]
[[lights]]
type = "directional"
direction = [0.4, -1.0, -0.3]
intensity = [0.8, 0.8, 0.75]
"""


def _scene(tmp_path, **kw):
    write_pbr_gltf(tmp_path / "pbr.gltf", **kw)
    (tmp_path / "scene.toml").write_text(SCENE)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = load_scene_file(str(tmp_path / "scene.toml"))
    return s, [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def test_all_five_texture_kinds_load_with_no_fallback(tmp_path):
    s, warned = _scene(tmp_path)
    assert warned == []                                   # nothing "not rendered"
    i = next(k for k, o in enumerate(s.desc.objects) if o.name.startswith("floor:"))
    m = s.desc.objects[i].material
    assert m.is_gltf_model and (m.metallic, m.roughness) == (1.0, 0.6)
    assert m.normal_scale == 0.7 and m.occlusion_strength == 0.8
    np.testing.assert_allclose(m.emission, [0.4, 0.6, 0.8])            # x emissiveStrength 2
    maps = s.maps[i]
    assert set(maps) == {"metallic_roughness", "normal_map", "emission_texture", "occlusion"}
    flip = lambda a: a[::-1] / 255.0   # noqa: E731  (row 0 is v = 0, the image's last row)
    # data textures as stored, colour textures sRGB-decoded
    np.testing.assert_allclose(maps["normal_map"], flip(IMAGES["normal"]), atol=1e-6)
    np.testing.assert_allclose(maps["metallic_roughness"], flip(IMAGES["mr"]), atol=1e-6)
    np.testing.assert_allclose(maps["occlusion"], flip(IMAGES["occlusion"]), atol=1e-6)
    e = flip(IMAGES["emissive"])
    np.testing.assert_allclose(maps["emission_texture"],
                               np.where(e <= 0.04045, e / 12.92, ((e + 0.055) / 1.055) ** 2.4), atol=1e-6)
    # and they reach the image: without the maps the floor shades differently
    from raster import Rasterizer
    r = Rasterizer(s, 48, 27)
    try:
        with_maps = r.render(0)["color"]
        geo = r.geometry(0)
        geo.maps.has_normal = geo.maps.has_mr = geo.maps.has_occlusion = geo.maps.has_emit_tex = False
        without = r.render(0)["color"]
    finally:
        r.close()
    assert np.all(np.isfinite(with_maps)) and np.abs(with_maps - without).max() > 0.05


def test_metallic_low_roughness_scene_meets_the_agreement_targets(tmp_path):
    s, _ = _scene(tmp_path)
    a = check_agreement(s, 64, 36, samples=64, cache=ReferenceCache(tmp_path / "cache"), progress=False)
    print(f"PBR glTF + metal sphere agreement: {a.agreement_psnr_db:.2f} dB, interior max |err| "
          f"{a.interior_max_abs_err:.2e} over {a.interior_pixels} px, reference noise "
          f"{a.reference_noise_psnr_db:.1f} dB")
    assert all(a.meets_targets().values()), a.meets_targets()
    assert a.agreement_psnr_db >= TARGETS["agreement_psnr_db"]
    assert a.interior_pixels > 0.5 * 64 * 36


def test_the_assets_own_tangents_orient_its_normal_map(tmp_path):
    """The floor's generated frame is T = +x, B = +z (u along x, our v along z). Given TANGENT
    (0, 0, 1, +1), T = +z and B = N x T = +x: swapping the texel's x and y must then give the same
    image, and the given tangent must matter."""
    def render(sub, **kw):
        (tmp_path / sub).mkdir()
        s, warned = _scene(tmp_path / sub, **kw)
        assert warned == []
        from raster import Rasterizer
        r = Rasterizer(s, 48, 27)
        try:
            return r.render(0)["color"]
        finally:
            r.close()
    given = render("given", tangent=(0.0, 0.0, 1.0, 1.0), normal_texel=(200, 128, 220))
    generated = render("generated", normal_texel=(128, 200, 220))
    ignored = render("ignored", normal_texel=(200, 128, 220))
    np.testing.assert_allclose(given, generated, rtol=1e-5, atol=1e-6)
    assert np.abs(given - ignored).max() > 0.05
    # a tangent along the normal has no direction: shaded finite (the raster refuses NaN buffers)
    assert np.all(np.isfinite(render("parallel", tangent=(0.0, 1.0, 0.0, 1.0), normal_texel=(200, 128, 220))))


@pytest.mark.parametrize("key, value", [("roughnessFactor", 1.5), ("metallicFactor", -0.5), ("roughnessFactor", "x")])
def test_a_factor_outside_0_1_is_refused_naming_the_file_and_field(tmp_path, key, value):
    write_pbr_gltf(tmp_path / "pbr.gltf")
    doc = json.loads((tmp_path / "pbr.gltf").read_text())
    doc["materials"][0]["pbrMetallicRoughness"][key] = value
    (tmp_path / "pbr.gltf").write_text(json.dumps(doc))
    (tmp_path / "scene.toml").write_text(SCENE)
    with pytest.raises(SceneError) as err:
        load_scene_file(str(tmp_path / "scene.toml"))
    msg = str(err.value)
    assert "pbr.gltf" in msg and f"materials[0].pbrMetallicRoughness.{key}" in msg and str(value) in msg


def test_a_zero_length_normal_texel_is_refused():
    flat = np.full((2, 2, 3), 0.75, np.float32)
    flat[1, 0] = 0.5                                     # decodes to (0, 0, 0)
    desc = Scene(name="z", camera=Camera(position=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0)), ambient=(0.2, 0.2, 0.2),
                 objects=(SceneObject(name="p", mesh=MeshSpec(kind="plane"),
                                      material=Material(roughness=0.5, normal_map=Texture(kind="array", data=flat))),))
    with pytest.raises(SceneError, match=r"objects\[0\] \('p'\)\.material\.normal_map: 1 texel.*row 1, column 0"):
        ResolvedScene(desc)
