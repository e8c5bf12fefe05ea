import json

import numpy as np
import pytest

from scenes import SceneError, builtin_names, get_scene
from scenes.jitter import halton_offset, halton_offsets
from scenes.loader import load_scene_file

GOOD = """
name = "user_scene"
transport = "direct"
frames = 3
[camera]
position = [0.0, 1.0, 4.0]
target = [0.0, 0.0, 0.0]
[[objects]]
name = "model"
mesh = { kind = "file", path = "model.obj" }
material = { albedo = [0.8, 0.2, 0.2] }
motion = { velocity = [0.1, 0.0, 0.0] }
[[lights]]
type = "directional"
direction = [0.0, -1.0, -1.0]
"""

OBJ = """v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
f 1 2 3
f 2 4 3
"""


def test_toml_scene_with_obj_written_here(tmp_path):
    (tmp_path / "model.obj").write_text(OBJ)
    (tmp_path / "scene.toml").write_text(GOOD)
    s = load_scene_file(str(tmp_path / "scene.toml"))
    assert s.name == "user_scene" and s.desc.frames == 3
    assert s.meshes[0].faces.tolist() == [[0, 1, 2], [1, 3, 2]]
    # frame 2 moves the model by 2 * velocity
    np.testing.assert_allclose(s.world_vertices(0, 2)[1], [1.2, 0, 0])
    assert "moving_object" in s.desc.features()


def test_json_scene_with_ply(tmp_path):
    import trimesh
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(tmp_path / "tri.ply")
    data = {"name": "j", "transport": "unlit", "camera": {"position": [0, 0, 3], "target": [0, 0, 0]},
            "objects": [{"name": "t", "mesh": {"kind": "file", "path": "tri.ply"}}]}
    (tmp_path / "s.json").write_text(json.dumps(data))
    s = load_scene_file(str(tmp_path / "s.json"))
    assert s.meshes[0].vertices.shape == (3, 3)


def test_bad_value_names_file_field_and_value(tmp_path):
    (tmp_path / "model.obj").write_text(OBJ)
    bad = GOOD.replace("albedo = [0.8, 0.2, 0.2]", 'albedo = "red"')
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(SceneError) as e:
        load_scene_file(str(tmp_path / "bad.toml"))
    msg = str(e.value)
    assert "bad.toml" in msg and "objects[0].material.albedo" in msg and "'red'" in msg


def test_negative_frames_and_unknown_field(tmp_path):
    (tmp_path / "a.toml").write_text(GOOD.replace("frames = 3", "frames = -2"))
    with pytest.raises(SceneError, match=r"field frames: .*-2"):
        load_scene_file(str(tmp_path / "a.toml"))
    (tmp_path / "b.toml").write_text(GOOD.replace("frames = 3", "frames = 3\nframez = 1"))
    with pytest.raises(SceneError, match="framez"):
        load_scene_file(str(tmp_path / "b.toml"))


def test_missing_mesh_path_is_named(tmp_path):
    (tmp_path / "scene.toml").write_text(GOOD)
    with pytest.raises(SceneError, match=r"mesh file not found: .*model\.obj"):
        load_scene_file(str(tmp_path / "scene.toml"))


def test_unparseable_file_is_named(tmp_path):
    (tmp_path / "x.toml").write_text("name = [unclosed")
    with pytest.raises(SceneError, match=r"x\.toml: cannot parse"):
        load_scene_file(str(tmp_path / "x.toml"))


def test_halton_sequence_skips_index_zero():
    assert halton_offset(0) == pytest.approx((0.0, 1 / 3 - 0.5))       # Halton index 1: (1/2, 1/3)
    assert halton_offset(1) == pytest.approx((-0.25, 2 / 3 - 0.5))      # index 2: (1/4, 2/3)
    assert halton_offset(2) == pytest.approx((0.25, 1 / 9 - 0.5))       # index 3: (3/4, 1/9)
    assert halton_offset(16) == halton_offset(0)                       # period 16 for TAA
    offs = halton_offsets(128)
    assert np.all(offs >= -0.5) and np.all(offs < 0.5)
    assert abs(offs.mean(axis=0)).max() < 0.02                          # well spread over the pixel


def test_builtin_scenes_resolve_and_hash_is_stable():
    for name in builtin_names():
        a, b = get_scene(name), get_scene(name)
        assert a.content_hash == b.content_hash
        assert sum(len(m.faces) for m in a.meshes) > 0
    assert get_scene("pipe").content_hash != get_scene("pipe_tilted").content_hash


def test_camera_cut_resets_and_moves_pose():
    from scenes.description import Camera, CameraCut
    from scenes.resolved import ResolvedScene
    from conftest import two_colour_scene
    s = two_colour_scene()
    cam = s.desc.camera.model_copy(update={"cuts": (CameraCut(frame=3, position=(1, 1, 5), target=(0, 0, 0)),)})
    s2 = ResolvedScene(s.desc.model_copy(update={"camera": Camera(**cam.model_dump())}))
    assert s2.is_cut(0) and s2.is_cut(3) and not s2.is_cut(2)
    np.testing.assert_allclose(s2.camera(4, 64, 64).position, [1, 1, 5])
    np.testing.assert_allclose(s2.camera(2, 64, 64).position, [0, 0, 5])


def test_readme_scene_example_loads(tmp_path):
    """The scene file docs/extending.md shows a user is valid as written."""
    import pathlib
    import re
    doc = (pathlib.Path(__file__).parent.parent / "docs" / "extending.md").read_text()
    block = re.search(r"```toml\n(.*?)```", doc[doc.index("## Your own scene"):], re.S).group(1)
    (tmp_path / "model.obj").write_text(OBJ)
    (tmp_path / "my_model.toml").write_text(block)
    s = load_scene_file(str(tmp_path / "my_model.toml"))
    assert s.desc.frames == 60 and s.textures[1] is not None
    assert set(s.desc.features()) >= {"direct_shadows", "texture", "moving_object", "moving_camera"}
