"""Whole glTF scenes. A multi-material GLB is written here with trimesh (nested
nodes, an sRGB base-colour texture, an alphaMode MASK cut-out, a camera), and a hand-assembled
.gltf exercises the decoder paths trimesh never writes (TRS quaternions, a mirroring node, a
triangle strip, interleaved and sparse accessors, normalised TEXCOORD_1, a nested camera)."""
import base64
import json
import struct
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from references import ReferenceCache
from scenes import SceneError, SceneWarning
from scenes.loader import load_scene_file
from study.engine.agreement import TARGETS, check_agreement
from study.commands.cli import main

BOARD_TEX = np.random.default_rng(7).integers(60, 200, (4, 4, 3), dtype=np.uint8)
LEAF_RGBA = np.array([[[200, 80, 40, 255], [200, 80, 40, 0]],
                      [[200, 80, 40, 0], [200, 80, 40, 255]]], np.uint8)   # a 2x2 alpha checker

SCENE = """
name = "gltf_scene"
transport = "direct"
ambient = [0.3, 0.3, 0.3]
background = [0.35, 0.4, 0.45]
[[objects]]
name = "g"
mesh = {{ kind = "gltf", path = "{path}", camera = {camera} }}
{extra}
[[lights]]
type = "directional"
direction = [-0.3, -1.0, -0.5]
"""


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _move(x, y, z):
    m = np.eye(4)
    m[:3, 3] = x, y, z
    return m


# Local node matrices; the world ones are their products along the hierarchy group > leaf > box.
LOCAL = {"floor": _rot_x(-np.pi / 2), "group": _move(-0.8, 0.8, 0.0),
         "leaf": _move(1.6, 0.0, 0.2) @ _rot_y(0.3), "box": _move(0.0, -0.8, 0.3)}
WORLD = {"floor": LOCAL["floor"], "group": LOCAL["group"], "leaf": LOCAL["group"] @ LOCAL["leaf"],
         "box": LOCAL["group"] @ LOCAL["leaf"] @ LOCAL["box"]}
QUAD_UV = [[0, 0], [1, 0], [1, 1], [0, 1]]
F32 = 1e-6   # the file stores positions as float32


def _quad(w, h):
    import trimesh
    v = np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]])
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def write_glb(path):
    """Four primitives on nested nodes with their own materials, and a camera at (0, 0.5, 4)."""
    import trimesh
    from PIL import Image
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial
    s = trimesh.Scene()
    floor = _quad(6, 6)
    floor.visual = TextureVisuals(uv=QUAD_UV, material=PBRMaterial(baseColorFactor=[0.6, 0.6, 0.6, 1.0],
                                                                   metallicFactor=0.0))
    s.add_geometry(floor, node_name="floor", geom_name="floor", transform=LOCAL["floor"])
    board = _quad(1.2, 1.2)
    board.visual = TextureVisuals(uv=QUAD_UV, material=PBRMaterial(
        baseColorFactor=[1.0, 1.0, 1.0, 1.0], baseColorTexture=Image.fromarray(BOARD_TEX, "RGB"),
        metallicFactor=0.0))
    s.add_geometry(board, node_name="group", geom_name="board", transform=LOCAL["group"])
    leaf = _quad(1.0, 1.0)
    leaf.visual = TextureVisuals(uv=QUAD_UV, material=PBRMaterial(
        baseColorFactor=[1.0, 1.0, 1.0, 1.0], baseColorTexture=Image.fromarray(LEAF_RGBA, "RGBA"),
        alphaMode="MASK", alphaCutoff=0.4, metallicFactor=0.0))
    s.add_geometry(leaf, node_name="leaf", parent_node_name="group", geom_name="leaf", transform=LOCAL["leaf"])
    box = trimesh.creation.box((0.5, 0.5, 0.5))
    box.visual = TextureVisuals(material=PBRMaterial(baseColorFactor=[0.2, 0.4, 0.9, 1.0], metallicFactor=0.0))
    s.add_geometry(box, node_name="box", parent_node_name="leaf", geom_name="box", transform=LOCAL["box"])
    s.camera_transform = _move(0.0, 0.5, 4.0)
    path.write_bytes(s.export(file_type="glb"))
    return box.vertices.copy()


def read_glb(path):
    raw = path.read_bytes()
    n = struct.unpack_from("<I", raw, 12)[0]
    doc = json.loads(raw[20:20 + n])
    m = struct.unpack_from("<I", raw, 20 + n)[0]
    return doc, raw[28 + n:28 + n + m]


def write_glb_json(path, doc, binary):
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(binary), 0x004E4942) + binary
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)


def scene_file(tmp_path, path="scene.glb", camera="true", extra=""):
    f = tmp_path / "scene.toml"
    f.write_text(SCENE.format(path=path, camera=camera, extra=extra))
    return str(f)


@pytest.fixture
def glb(tmp_path):
    box = write_glb(tmp_path / "scene.glb")
    return tmp_path, box


def _srgb_to_linear(c8):
    c = c8 / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _by_name(s):
    return {o.name.split(":")[1].split("#")[0]: i for i, o in enumerate(s.desc.objects)}


def test_each_primitive_gets_its_node_transform_and_material(glb):
    tmp, box = glb
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)      # this file uses nothing unsupported
        s = load_scene_file(scene_file(tmp))
    idx = _by_name(s)
    assert sorted(idx) == ["box", "floor", "group", "leaf"] and len(s.meshes) == 4
    # Vertices after the node hierarchy, by hand for two of them ...
    np.testing.assert_allclose(s.world_vertices(idx["group"], 0)[0], [-1.4, 0.2, 0.0], atol=F32)
    np.testing.assert_allclose(s.world_vertices(idx["floor"], 0)[0], [-3.0, 0.0, 3.0], atol=F32)
    # ... and every vertex of the box, three levels deep, against the product of the local matrices.
    want = box @ WORLD["box"][:3, :3].T + WORLD["box"][:3, 3]
    np.testing.assert_allclose(s.world_vertices(idx["box"], 0), want, atol=F32)
    np.testing.assert_allclose(s.world_vertices(idx["box"], 0)[0],
                               [-0.8 + 1.6 + np.sin(0.3) * (0.3 - 0.25) - 0.25 * np.cos(0.3),
                                0.8 - 0.8 - 0.25, 0.2 + np.cos(0.3) * (0.3 - 0.25) + 0.25 * np.sin(0.3)],
                               atol=F32)
    mats = {k: s.desc.objects[i].material for k, i in idx.items()}
    # trimesh stores colour factors as 8-bit values
    np.testing.assert_allclose(mats["floor"].albedo, [0.6] * 3, atol=0.5 / 255)
    np.testing.assert_allclose(mats["box"].albedo, [0.2, 0.4, 0.9], atol=0.5 / 255)
    np.testing.assert_allclose(mats["group"].albedo, [1.0] * 3)
    assert s.textures[idx["floor"]] is None and s.textures[idx["box"]] is None
    # The board's texture: sRGB decoded, rows flipped so that row 0 is v = 0 (the image's bottom).
    np.testing.assert_allclose(s.textures[idx["group"]], _srgb_to_linear(BOARD_TEX[::-1]), atol=1e-6)
    # glTF's v runs down the image; ours up: the quad's corners keep their texels.
    np.testing.assert_allclose(s.meshes[idx["group"]].uvs, QUAD_UV, atol=1e-7)
    # The leaf: its own texture and the alpha channel as the cut-out at alphaCutoff.
    assert s.alphas[idx["leaf"]].tolist() == (LEAF_RGBA[::-1, :, 3] / 255.0).tolist()
    assert mats["leaf"].alpha_threshold == pytest.approx(0.4)
    assert all(s.alphas[idx[k]] is None for k in ("floor", "group", "box"))
    assert set(s.desc.features()) >= {"texture", "alpha_cutout"}


def test_the_files_camera_and_the_objects_transform_on_top(glb):
    tmp, box = glb
    s = load_scene_file(scene_file(tmp))
    c = s.desc.camera
    assert c.position == pytest.approx((0.0, 0.5, 4.0)) and c.target == pytest.approx((0.0, 0.5, 3.0))
    assert c.up == pytest.approx((0.0, 1.0, 0.0)) and c.near == pytest.approx(0.01)
    assert c.yfov_deg == pytest.approx(45.0)          # trimesh's default camera
    # No zfar in the file: far lies just beyond the farthest corner of the bounding box.
    corners = np.array([[x, y, z] for x in (-3, 3) for y in (-0.25, 1.4) for z in (-3, 3)], float)
    assert np.linalg.norm(corners - c.position, axis=1).max() < c.far < 8.0
    # A transform on the glTF object moves every primitive and the camera with it.
    t = 'transform = { translate = [1.0, 2.0, 3.0], rotate_axis = [0.0, 1.0, 0.0], rotate_deg = 90.0 }'
    moved = load_scene_file(scene_file(tmp, extra=t))
    rot = _rot_y(np.pi / 2)[:3, :3]
    idx = _by_name(moved)
    np.testing.assert_allclose(moved.world_vertices(idx["box"], 0),
                               (box @ WORLD["box"][:3, :3].T + WORLD["box"][:3, 3]) @ rot.T + [1, 2, 3],
                               atol=F32)
    np.testing.assert_allclose(moved.desc.camera.position, rot @ [0, 0.5, 4] + [1, 2, 3], atol=F32)
    np.testing.assert_allclose(moved.desc.camera.target, rot @ [0, 0.5, 3] + [1, 2, 3], atol=F32)


def test_scene_file_camera_fields_override_and_move_the_gltf_camera(glb):
    tmp, _ = glb
    extra = '[camera]\nyfov_deg = 30.0\nfar = 40.0\nvelocity = [0.1, 0.0, 0.0]'
    s = load_scene_file(scene_file(tmp, extra=extra))
    c = s.desc.camera
    assert c.yfov_deg == 30.0 and c.far == 40.0 and c.near == pytest.approx(0.01)
    assert c.position == pytest.approx((0.0, 0.5, 4.0))
    np.testing.assert_allclose(s.camera(3, 64, 36).position, [0.3, 0.5, 4.0], atol=1e-12)
    # With camera = false the scene file must say where the camera is.
    with pytest.raises(SceneError, match="camera needs a position and a target"):
        load_scene_file(scene_file(tmp, camera="false"))
    own = '[camera]\nposition = [0.0, 1.0, 6.0]\ntarget = [0.0, 0.0, 0.0]'
    s = load_scene_file(scene_file(tmp, camera="false", extra=own))
    assert s.desc.camera.position == (0.0, 1.0, 6.0) and s.desc.camera.yfov_deg == 45.0


def test_agreement_of_the_multi_material_scene(glb, tmp_path):
    tmp, _ = glb
    s = load_scene_file(scene_file(tmp))
    a = check_agreement(s, 64, 36, samples=64, cache=ReferenceCache(tmp_path / "cache"), progress=False)
    print(f"glTF scene agreement: {a.agreement_psnr_db:.2f} dB, interior max |err| "
          f"{a.interior_max_abs_err:.2e} over {a.interior_pixels} px, reference noise "
          f"{a.reference_noise_psnr_db:.1f} dB, visible {a.visible_fraction:.2f}")
    assert a.agreement_psnr_db >= TARGETS["agreement_psnr_db"]
    assert a.interior_max_abs_err <= TARGETS["interior_max_abs_err"]
    assert a.interior_pixels > 0.5 * 64 * 36 and a.visible_fraction > 0.4
    assert a.single_sample and a.centre_match_fraction > 0.99


def test_unsupported_features_are_listed_once_naming_the_file(glb):
    tmp, _ = glb
    doc, binary = read_glb(tmp / "scene.glb")
    mats = doc["materials"]
    leaf = next(m for m in mats if m.get("alphaMode") == "MASK")
    leaf["normalTexture"] = {"index": 0}
    leaf["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": 0}
    opaque = [m for m in mats if "alphaMode" not in m]
    opaque[0]["alphaMode"] = "BLEND"
    opaque[1]["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0}}
    doc["extensionsUsed"] = ["KHR_materials_clearcoat"]
    write_glb_json(tmp / "scene.glb", doc, binary)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = load_scene_file(scene_file(tmp))
    mine = [w for w in caught if issubclass(w.category, SceneWarning)]
    assert len(mine) == 1, [str(w.message) for w in mine]
    msg = str(mine[0].message)
    assert "\n" not in msg and "scene.glb" in msg and "scene.toml" in msg
    for feature in ("KHR_materials_clearcoat", "alphaMode BLEND (cut out as MASK at 0.5)"):
        assert feature in msg
    for read in ("normalTexture", "metallicRoughnessTexture", "metallicFactor"):   # rendered now
        assert read not in msg
    # BLEND with a constant alpha of 1 keeps everything; all four primitives are still there.
    assert len(s.meshes) == 4


def test_content_hash_covers_the_gltf_file(glb):
    import io
    from PIL import Image
    tmp, _ = glb
    f = scene_file(tmp)
    h0 = load_scene_file(f).content_hash
    assert load_scene_file(f).content_hash == h0
    original = (tmp / "scene.glb").read_bytes()
    doc, binary = read_glb(tmp / "scene.glb")
    # An edit that changes nothing drawn (a roughness factor) still re-keys the references.
    doc["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = 0.25
    write_glb_json(tmp / "scene.glb", doc, binary)
    h1 = load_scene_file(f).content_hash
    assert h1 != h0
    (tmp / "scene.glb").write_bytes(original)
    assert load_scene_file(f).content_hash == h0
    # One texel of the board's PNG: appended as a new buffer view that the image now points at.
    doc, binary = read_glb(tmp / "scene.glb")
    board = next(m for m in doc["materials"] if "baseColorTexture" in m["pbrMetallicRoughness"]
                 and "alphaMode" not in m)
    image = doc["textures"][board["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"]
    tex = BOARD_TEX.copy()
    tex[0, 0] = 0
    png = io.BytesIO()
    Image.fromarray(tex, "RGB").save(png, format="PNG")
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(png.getvalue())})
    doc["images"][image] = {"bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png"}
    binary += png.getvalue()
    doc["buffers"][0]["byteLength"] = len(binary)
    write_glb_json(tmp / "scene.glb", doc, binary)
    s2 = load_scene_file(f)
    assert s2.content_hash not in (h0, h1)
    assert s2.textures[_by_name(s2)["group"]][-1, 0].tolist() == [0.0, 0.0, 0.0]   # image row 0 is our last


def _hand_gltf(tmp_path, camera_type="perspective"):
    """Positions and normals interleaved (stride 24), vertex 3 replaced by a sparse accessor,
    TEXCOORD_1 as normalised uint16; a strip under a mirroring node under a rotated, moved root."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    inter = np.concatenate([pos, nrm], 1).tobytes()                       # 96 bytes
    uv0 = np.zeros((4, 2), np.float32).tobytes()                           # 32 bytes
    uv1 = np.array([[0, 0], [65535, 0], [0, 65535], [65535, 65535]], np.uint16).tobytes()   # 16
    sparse_idx = np.array([3], np.uint16).tobytes() + b"\0\0"             # 4 (padded)
    sparse_val = np.array([[2, 2, 0]], np.float32).tobytes()               # 12
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1]], np.float32).tobytes()  # 36
    data = inter + uv0 + uv1 + sparse_idx + sparse_val + tri
    from PIL import Image
    import io
    png = io.BytesIO()
    Image.fromarray(np.array([[[255, 0, 0], [0, 0, 255]]], np.uint8), "RGB").save(png, format="PNG")
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 96, "byteStride": 24},
             {"buffer": 0, "byteOffset": 96, "byteLength": 32},
             {"buffer": 0, "byteOffset": 128, "byteLength": 16},
             {"buffer": 0, "byteOffset": 144, "byteLength": 4},
             {"buffer": 0, "byteOffset": 148, "byteLength": 12},
             {"buffer": 0, "byteOffset": 160, "byteLength": 36}]
    h = np.sqrt(0.5)
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 2]}],
        "nodes": [{"name": "root", "translation": [1, 0, 0], "rotation": [0, 0, h, h], "children": [1]},
                  {"name": "mirror", "scale": [-1, 1, 1], "mesh": 0},
                  {"name": "rig", "translation": [0, 1, 0], "children": [3]},
                  {"name": "cam", "translation": [0, 0, 5], "camera": 0}],
        "cameras": [{"type": camera_type, "perspective": {"yfov": 0.5, "znear": 0.05, "zfar": 50.0}}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3}, "mode": 5,
             "material": 0},
            {"attributes": {"POSITION": 4}}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1},
                                                "metallicFactor": 0.0}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}],
        "accessors": [
            {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "sparse": {"count": 1, "indices": {"bufferView": 3, "componentType": 5123},
                        "values": {"bufferView": 4}}},
            {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "normalized": True, "count": 4, "type": "VEC2"},
            {"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "bufferViews": views,
        "buffers": [{"byteLength": len(data), "uri": "hand.bin"}],
    }
    (tmp_path / "hand.bin").write_bytes(data)
    (tmp_path / "hand.gltf").write_text(json.dumps(doc))
    return doc


def test_decoder_paths_by_hand(tmp_path):
    _hand_gltf(tmp_path)
    s = load_scene_file(scene_file(tmp_path, path="hand.gltf"))
    assert len(s.meshes) == 2
    strip, tri = s.meshes
    # world = T(1,0,0) Rz(90) S(-1,1,1): (x, y, z) -> (1 - y, -x, z); vertex 3 comes from the sparse values.
    np.testing.assert_allclose(strip.vertices, [[1, 0, 0], [1, -1, 0], [0, 0, 0], [-1, -2, 0]], atol=1e-12)
    # The strip is (0,1,2), (2,1,3); the mirror reverses both triangles' winding ...
    assert strip.faces.tolist() == [[2, 1, 0], [3, 1, 2]]
    # ... so their geometric normals agree with the (rotated, mirrored) vertex normals, +z.
    v = strip.vertices[strip.faces]
    geo_n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    np.testing.assert_allclose(geo_n / np.linalg.norm(geo_n, axis=1, keepdims=True), [[0, 0, 1]] * 2, atol=1e-12)
    np.testing.assert_allclose(strip.normals, [[0, 0, 1]] * 4, atol=1e-12)
    # texCoord 1 (normalised uint16), v flipped; TEXCOORD_0 is all zeros and must not be used.
    np.testing.assert_allclose(strip.uvs, [[0, 1], [1, 1], [0, 0], [1, 0]], atol=1e-12)
    np.testing.assert_allclose(s.textures[0][0], _srgb_to_linear(np.array([[255, 0, 0], [0, 0, 255]])), atol=1e-6)
    # The second primitive: no indices, no material -> the spec's default white.
    assert tri.faces.tolist() == [[2, 1, 0]] and s.desc.objects[1].material.albedo == (1.0, 1.0, 1.0)
    # The camera two levels deep: (0, 1, 0) + (0, 0, 5).
    c = s.desc.camera
    assert c.position == pytest.approx((0.0, 1.0, 5.0)) and c.target == pytest.approx((0.0, 1.0, 4.0))
    assert c.yfov_deg == pytest.approx(np.degrees(0.5)) and (c.near, c.far) == (0.05, 50.0)


@pytest.mark.parametrize("edit,message", [
    (lambda d: d["accessors"][4].update(count=40), "accessors[4]: 40 elements need"),
    (lambda d: d["cameras"][0].update(type="orthographic"), "cameras[0].type: only perspective"),
    (lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]), "extensionsRequired"),
    (lambda d: d["nodes"][0].update(children=[1, 0]), "not a tree"),
    (lambda d: d["nodes"][1].update(scale=[0, 1, 1]), "nodes[1]: world transform is singular"),
    (lambda d: d["meshes"][0]["primitives"][0].update(material=5), "materials index 5 out of range"),
    (lambda d: d["buffers"][0].update(uri="gone.bin"), "buffers[0].uri: file not found"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].pop("TEXCOORD_1"), "TEXCOORD_1"),
    (lambda d: d["materials"][0]["pbrMetallicRoughness"].update(baseColorFactor=[1, 1]), "baseColorFactor"),
])
def test_malformed_gltf_names_the_file_and_the_field(tmp_path, edit, message):
    doc = _hand_gltf(tmp_path)
    edit(doc)
    (tmp_path / "hand.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneError) as err:
        load_scene_file(scene_file(tmp_path, path="hand.gltf"))
    assert "hand.gltf" in str(err.value) and "objects[0] ('g').mesh" in str(err.value)
    assert message in str(err.value)


def test_cli_exits_2_on_a_missing_or_corrupt_gltf(tmp_path):
    f = scene_file(tmp_path, path="nowhere.glb")
    r = CliRunner().invoke(main, ["agree", "--scene", f])
    assert r.exit_code == 2 and "nowhere.glb" in r.output and "Traceback" not in r.output
    (tmp_path / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00\xff\x00\x00\x00")
    r = CliRunner().invoke(main, ["agree", "--scene", scene_file(tmp_path, path="broken.glb")])
    assert r.exit_code == 2 and "broken.glb" in r.output and "truncated" in r.output
    write_glb(tmp_path / "scene.glb")
    r = CliRunner().invoke(main, ["agree", "--scene", scene_file(
        tmp_path, extra='material = { albedo = [1.0, 0.0, 0.0] }')])
    assert r.exit_code == 2 and "takes its materials from the file" in r.output


def test_instanced_mesh_shares_its_texture(tmp_path):
    """Two nodes placing one mesh: two objects each, one decoded texture, stored once for shading."""
    from shading.frame import frame_geometry
    doc = _hand_gltf(tmp_path)
    doc["nodes"].append({"name": "copy", "translation": [0, 0, -2], "mesh": 0})
    doc["scenes"][0]["nodes"].append(4)
    (tmp_path / "hand.gltf").write_text(json.dumps(doc))
    s = load_scene_file(scene_file(tmp_path, path="hand.gltf"))
    assert [o.name for o in s.desc.objects] == ["g:mirror#1.0", "g:mirror#1.1", "g:copy#4.0", "g:copy#4.1"]
    np.testing.assert_allclose(s.meshes[2].vertices, [[0, 0, -2], [1, 0, -2], [0, 1, -2], [2, 2, -2]], atol=1e-12)
    assert s.textures[0] is s.textures[2]
    geo = frame_geometry(s, 0)
    table = np.asarray(geo.obj_tex).reshape(-1, 3)      # per object id: offset, width, height
    assert table[1].tolist() == table[3].tolist() == [0, 2, 1] and table[2].tolist() == [0, 0, 0]
    assert np.asarray(geo.tex_data).size == 2 * 3


def test_triangle_fan(tmp_path):
    doc = _hand_gltf(tmp_path)
    doc["meshes"][0]["primitives"][0]["mode"] = 6
    (tmp_path / "hand.gltf").write_text(json.dumps(doc))
    s = load_scene_file(scene_file(tmp_path, path="hand.gltf"))
    # The fan (1,2,0), (2,3,0), reversed by the mirroring node.
    assert s.meshes[0].faces.tolist() == [[0, 2, 1], [0, 3, 2]]


def test_zero_area_triangles_are_dropped_and_counted_in_the_one_warning(tmp_path):
    _hand_gltf(tmp_path)
    data = bytearray((tmp_path / "hand.bin").read_bytes())
    data[148:160] = np.array([2, -1, 0], np.float32).tobytes()   # vertex 3 onto the line through 1 and 2
    (tmp_path / "hand.bin").write_bytes(bytes(data))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = load_scene_file(scene_file(tmp_path, path="hand.gltf"))
    msgs = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert len(msgs) == 1 and "1 zero-area triangles (dropped)" in msgs[0] and "hand.gltf" in msgs[0]
    assert s.meshes[0].faces.tolist() == [[2, 1, 0]]


def test_alpha_cutoff_defaults_to_the_specs_half(glb):
    # glTF 2.0, material.alphaCutoff: "Specifies the cutoff threshold when in MASK alpha mode ...
    # default 0.5" — a MASK material without the field cuts out at 0.5
    tmp, _ = glb
    doc, binary = read_glb(tmp / "scene.glb")
    leaf = next(m for m in doc["materials"] if m.get("alphaMode") == "MASK")
    del leaf["alphaCutoff"]
    write_glb_json(tmp / "scene.glb", doc, binary)
    s = load_scene_file(scene_file(tmp))
    assert s.desc.objects[_by_name(s)["leaf"]].material.alpha_threshold == 0.5
