"""Validation at the boundary: scene numbers, directions, meshes, OBJ encodings and the
EXR writer's output hygiene (stdout, file mode)."""
import copy
import json
import os
import re
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from scenes import SceneError
from scenes.loader import load_scene_file
from scenes.meshes import SceneWarning, degenerate_faces

# A scene that sets every numeric field the description has, so the walk below reaches them all.
FULL = {
    "name": "full", "transport": "direct", "frames": 4,
    "camera": {"position": [0.0, 1.0, 5.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
               "yfov_deg": 40.0, "near": 0.1, "far": 50.0, "velocity": [0.01, 0.0, 0.0],
               "target_velocity": [0.0, 0.01, 0.0],
               "cuts": [{"frame": 2, "position": [1.0, 1.0, 5.0], "target": [0.0, 0.0, 0.0]}]},
    "objects": [
        {"name": "ball", "mesh": {"kind": "sphere", "radius": 0.5, "segments": 8, "uv_scale": [1.0, 2.0]},
         "material": {"albedo": [0.5, 0.5, 0.5], "emission": [0.0, 0.0, 0.1], "alpha_threshold": 0.5,
                      "texture": {"kind": "checker", "squares": 4, "color_a": [1.0, 1.0, 1.0],
                                  "color_b": [0.1, 0.1, 0.1]}},
         "transform": {"translate": [0.0, 0.5, 0.0], "rotate_axis": [0.0, 0.0, 1.0], "rotate_deg": 10.0,
                       "scale": [1.0, 2.0, 1.0]},
         "motion": {"velocity": [0.02, 0.0, 0.0], "spin_axis": [0.0, 1.0, 0.0], "spin_deg": 3.0}},
        {"name": "floor", "mesh": {"kind": "box", "size": [4.0, 0.1, 4.0]}},
    ],
    "lights": [{"type": "directional", "direction": [0.0, -1.0, -1.0], "intensity": [1.0, 1.0, 1.0]},
               {"type": "point", "position": [0.0, 3.0, 0.0], "intensity": [2.0, 2.0, 2.0]}],
    "ambient": [0.05, 0.05, 0.05], "background": [0.1, 0.1, 0.2],
}


def _float_leaves(node, path=""):
    """(field path as the loader prints it, container, key) for every float in the description."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _float_leaves(v, f"{path}.{k}" if path else k) if isinstance(v, (dict, list)) \
                else ([(f"{path}.{k}" if path else k, node, k)] if isinstance(v, float) else [])
    elif isinstance(node, list):
        for i, v in enumerate(node):
            if isinstance(v, (dict, list)):
                yield from _float_leaves(v, f"{path}[{i}]")
            elif isinstance(v, float):
                yield f"{path}[{i}]", node, i


def _write_json(tmp_path, data, name="s.json"):
    p = tmp_path / name
    p.write_text(json.dumps(data))        # json writes NaN / Infinity, as a user's file may
    return str(p)


def test_full_scene_is_valid(tmp_path):
    s = load_scene_file(_write_json(tmp_path, FULL))
    assert len(s.meshes) == 2 and s.desc.frames == 4


def test_every_number_must_be_finite(tmp_path):
    """Row 'camera position NaN' / 'light intensity Inf', for every float field at once."""
    leaves = list(_float_leaves(FULL))
    assert len(leaves) > 50            # the walk really covers the description
    for bad in (float("nan"), float("inf"), float("-inf")):
        for i, (field, _, _) in enumerate(leaves):
            data = copy.deepcopy(FULL)
            _, node, key = list(_float_leaves(data))[i]
            node[key] = bad
            with pytest.raises(SceneError) as e:
                load_scene_file(_write_json(tmp_path, data))
            msg = str(e.value)
            assert "s.json" in msg and f"field {field}:" in msg and repr(bad) in msg, (field, msg)


def test_toml_nan_camera_and_inf_intensity_named(tmp_path):
    scene = """name = "t"
[camera]
position = [nan, 1.0, 4.0]
target = [0.0, 0.0, 0.0]
[[objects]]
name = "box"
mesh = { kind = "box" }
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
intensity = [1.0, inf, 1.0]
"""
    (tmp_path / "bad.toml").write_text(scene)
    with pytest.raises(SceneError) as e:
        load_scene_file(str(tmp_path / "bad.toml"))
    msg = str(e.value)
    assert "bad.toml" in msg
    assert "field camera.position[0]: Input should be a finite number (value: nan)" in msg
    # the union tag ('directional') pydantic puts in its location is not part of the path
    assert "field lights[0].intensity[1]: Input should be a finite number (value: inf)" in msg


@pytest.mark.parametrize("field, set_to", [
    ("lights[0].direction", lambda d: d["lights"][0].update(direction=[0.0, 0.0, 0.0])),
    ("objects[0].motion.spin_axis", lambda d: d["objects"][0]["motion"].update(spin_axis=[0.0, 0.0, 0.0])),
    ("objects[0].transform.rotate_axis",
     lambda d: d["objects"][0]["transform"].update(rotate_axis=[0.0, 0.0, 0.0])),
    ("camera.up", lambda d: d["camera"].update(up=[0.0, 0.0, 0.0])),
])
def test_zero_direction_is_an_error(tmp_path, field, set_to):
    data = copy.deepcopy(FULL)
    set_to(data)
    want = f"field {field}: must be a non-zero direction (value: [0.0, 0.0, 0.0])"
    with pytest.raises(SceneError, match=re.escape(want)):
        load_scene_file(_write_json(tmp_path, data))


def test_camera_on_its_target_or_up_along_view(tmp_path):
    data = copy.deepcopy(FULL)
    data["camera"].update(position=[0.0, 0.0, 0.0])
    with pytest.raises(SceneError, match=r"field camera: position \(0\.0, 0\.0, 0\.0\) and target .* coincide"):
        load_scene_file(_write_json(tmp_path, data))
    data = copy.deepcopy(FULL)
    data["camera"]["cuts"][0].update(target=[1.0, 1.0, 5.0])
    with pytest.raises(SceneError, match=r"field camera\.cuts\[0\]: position .* coincide"):
        load_scene_file(_write_json(tmp_path, data))
    # each value valid, the animation not: at frame 1 the camera reaches its target
    data = copy.deepcopy(FULL)
    data["camera"].update(position=[0.0, 0.0, 1.0], velocity=[0.0, 0.0, -1.0], target_velocity=[0.0, 0.0, 0.0])
    with pytest.raises(SceneError, match=r"s\.json: camera: at frame 1 .* no view direction"):
        load_scene_file(_write_json(tmp_path, data))
    data = copy.deepcopy(FULL)
    data["camera"].update(position=[0.0, 5.0, 0.0], velocity=[0.0, 0.0, 0.0], target_velocity=[0.0, 0.0, 0.0])
    with pytest.raises(SceneError, match=r"camera: at frame 0: camera up .* parallel to the view direction"):
        load_scene_file(_write_json(tmp_path, data))


def test_scale_zero_is_an_error(tmp_path):
    data = copy.deepcopy(FULL)
    data["objects"][1]["transform"] = {"scale": [1.0, 0.0, 1.0]}
    with pytest.raises(SceneError, match=r"field objects\[1\]\.transform\.scale: a zero scale component"):
        load_scene_file(_write_json(tmp_path, data))


def test_overflowing_motion_is_an_error(tmp_path):
    data = copy.deepcopy(FULL)
    data["objects"][0]["motion"]["velocity"] = [1e308, 0.0, 0.0]
    with pytest.raises(SceneError, match=r"objects\[0\] \('ball'\): world positions overflow at frame 3"):
        load_scene_file(_write_json(tmp_path, data))


OBJ_HEAD = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
SCENE_WITH_OBJ = """name = "m"
transport = "unlit"
[camera]
position = [0.5, 0.5, 3.0]
target = [0.5, 0.5, 0.0]
[[objects]]
name = "model"
mesh = { kind = "file", path = "model.obj" }
"""


def _load_obj_scene(tmp_path, obj_bytes):
    (tmp_path / "model.obj").write_bytes(obj_bytes)
    (tmp_path / "scene.toml").write_text(SCENE_WITH_OBJ)
    return load_scene_file(str(tmp_path / "scene.toml"))


def test_all_degenerate_mesh_is_an_error_naming_object_and_files(tmp_path):
    # both triangles lie on the x axis (collinear vertices) or repeat a vertex
    obj = OBJ_HEAD + "f 1 2 4\nf 3 3 1\n"
    with pytest.raises(SceneError) as e:
        _load_obj_scene(tmp_path, obj.encode())
    msg = str(e.value)
    assert "scene.toml: objects[0] ('model').mesh (file model.obj): all 2 triangles are degenerate" in msg


def test_partly_degenerate_mesh_warns_once(tmp_path):
    obj = OBJ_HEAD + "f 1 2 3\nf 1 2 4\n"
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        s = _load_obj_scene(tmp_path, obj.encode())
    mine = [w for w in got if issubclass(w.category, SceneWarning)]
    assert len(mine) == 1
    assert "scene.toml: objects[0] ('model').mesh (file model.obj): 1 of 2 triangles are degenerate" \
        in str(mine[0].message)
    assert len(s.meshes[0].faces) == 2            # kept: they cover no pixel anyway


def test_builtin_scenes_have_no_degenerate_triangles():
    from scenes import builtin_names, get_scene
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        for name in builtin_names():
            get_scene(name)


def test_degenerate_mask_by_hand():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [1, 1e-13, 0], [1, 1e-6, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [0, 0, 2], [0, 3, 4], [0, 3, 5]])
    # area/longest^2: 0.5, 0 (collinear), 0 (repeated vertex), 2.5e-14 (a line), 2.5e-7 (a sliver)
    assert degenerate_faces(v, f).tolist() == [False, True, True, True, False]


@pytest.mark.parametrize("encoding", ["latin-1", "cp1252", "utf-8-sig", "utf-16"])
def test_obj_in_any_encoding_loads(tmp_path, encoding):
    """Row 'OBJ with a Latin-1 byte in a comment'; a UTF-8 BOM must not eat the first vertex."""
    text = OBJ_HEAD + "# modelo de prueba: café, Ø 12 mm\nf 1 2 3\nf 2 4 3\n"
    raw = text.encode(encoding)
    if encoding == "latin-1":
        assert b"caf\xe9" in raw
    s = _load_obj_scene(tmp_path, raw)
    np.testing.assert_array_equal(s.meshes[0].vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    assert s.meshes[0].faces.tolist() == [[0, 1, 2], [1, 3, 2]]


# -- the CLI ends with exit 2 and a message, no traceback -----------------------------------------
@pytest.mark.parametrize("command", ["render", "agree"])
@pytest.mark.parametrize("field, value, shown", [
    ("camera.position[0]", float("nan"), "nan"),
    ("lights[0].intensity[0]", float("inf"), "inf"),
    ("lights[0].direction[1]", float("nan"), "nan"),
])
def test_cli_exits_2_on_a_bad_scene(tmp_path, command, field, value, shown):
    from study.commands.cli import main
    data = copy.deepcopy(FULL)
    for path, node, key in _float_leaves(data):
        if path == field:
            node[key] = value
    scene = _write_json(tmp_path, data, "bad.json")
    res = CliRunner().invoke(main, [command, "--scene", scene, "--out", str(tmp_path / "out")]
                             if command == "render" else [command, "--scene", scene])
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit)
    assert "Traceback" not in res.output and res.stdout == ""
    assert "bad.json" in res.stderr and f"field {field}: Input should be a finite number (value: {shown})" \
        in res.stderr
    assert not (tmp_path / "out").exists()        # nothing rendered


def test_cli_exits_2_on_all_degenerate_mesh(tmp_path):
    from study.commands.cli import main
    (tmp_path / "model.obj").write_text(OBJ_HEAD + "f 1 2 4\n")
    (tmp_path / "scene.toml").write_text(SCENE_WITH_OBJ)
    res = CliRunner().invoke(main, ["agree", "--scene", str(tmp_path / "scene.toml")])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "objects[0] ('model').mesh (file model.obj): all 1 triangles are degenerate" in res.stderr


# -- EXR files ------------------------------------------------------------------------------------
def _truncated_exr(tmp_path):
    """Cut in the pixel data, where OpenEXR prints its 'Exception raised reading pixel data'."""
    from references.exr import write_exr
    path = tmp_path / "r.exr"
    write_exr(path, {"RGB": np.linspace(0, 1, 24 * 32 * 3).reshape(24, 32, 3)})
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    return path


def test_truncated_exr_read_prints_nothing_on_stdout(tmp_path, capfd):
    """Row 'a truncated reference EXR': OpenEXR's warning must not reach stdout (`ab --json`)."""
    from references.exr import ExrError, read_exr
    path = _truncated_exr(tmp_path)
    capfd.readouterr()
    with pytest.raises(ExrError) as e:
        read_exr(path)
    out, err = capfd.readouterr()
    assert out == ""
    # the library's stdout warning is folded into the message, which names the file
    assert str(path) in str(e.value) and "Exception raised reading pixel data" in str(e.value)
    assert isinstance(e.value, ValueError)       # what the reference cache and the store catch


def test_exr_stdout_hygiene_in_a_child_process(tmp_path):
    """The same in a process whose stdout is a pipe, as under `taa-study ab --json | jq`."""
    import subprocess
    import sys
    path = _truncated_exr(tmp_path)
    code = ("import json, sys; from references.exr import read_exr\n"
            f"try: read_exr({str(path)!r})\nexcept ValueError as e: print('caught', file=sys.stderr)\n"
            "print(json.dumps({'ok': 1}))\n")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, timeout=60)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout) == {"ok": 1}
    assert "caught" in p.stderr


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640)])
def test_exr_files_get_the_users_umask(tmp_path, umask, mode):
    """Row 'every file written: mode 0600', for EXR files."""
    from references.exr import read_exr, write_exr
    old = os.umask(umask)
    try:
        write_exr(tmp_path / "a.exr", {"Y": np.zeros((24, 32))})
        write_exr(tmp_path / "a.exr", {"Y": np.ones((24, 32))})      # replacing keeps it too
    finally:
        os.umask(old)
    assert (tmp_path / "a.exr").stat().st_mode & 0o777 == mode
    assert read_exr(tmp_path / "a.exr")[1]["Y"].mean() == 1.0
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]          # no temporary left
