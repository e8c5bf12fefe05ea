"""Bad textures exit 2 naming the scene file, the field and the value: a file that is not an image,
a float image holding NaN/Inf, an empty array, a filter that does not exist."""
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from scenes.description import Scene
from study.commands.cli import main

SCENE = '''name = "tex"
transport = "unlit"
camera = {{ position = [0.0, 0.0, 1.0], target = [0.0, 0.0, 0.0] }}
[[objects]]
name = "p"
mesh = {{ kind = "plane" }}
material = {{ texture = {{ kind = "image", path = "{path}", filter = "{filt}" }} }}
'''


def _nan_tiff(p):
    a = np.ones((4, 5), np.float32)
    a[2, 3], a[3, 1] = np.nan, np.inf
    Image.fromarray(a, mode="F").save(p)


@pytest.mark.parametrize("name,make,filt,words", [
    ("nan.tiff", _nan_tiff, "trilinear", ["material.texture", "nan.tiff", "2 NaN/Inf texel(s)", "row 2, column 3"]),
    ("text.png", lambda p: p.write_text("not an image"), "bilinear", ["material.texture", "cannot read texture", "text.png"]),
    ("ok.png", lambda p: Image.new("RGB", (3, 5)).save(p), "anisotropic",
     ["material.texture.filter", "'anisotropic'"]),
])
def test_a_bad_texture_exits_2_naming_file_field_and_value(tmp_path, name, make, filt, words):
    make(tmp_path / name)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(path=name, filt=filt))
    r = CliRunner().invoke(main, ["agree", "--scene", str(scene), "--width", "16", "--height", "9"])
    assert r.exit_code == 2, r.output
    assert "scene.toml" in r.output and "Traceback" not in r.output
    for w in words:
        assert w in r.output, (w, r.output)


def test_an_empty_array_texture_is_refused():
    d = {"name": "e", "transport": "unlit", "camera": {"position": [0, 0, 1], "target": [0, 0, 0]},
         "objects": [{"name": "p", "mesh": {"kind": "plane"},
                      "material": {"texture": {"kind": "array", "data": np.zeros((0, 4, 3), np.float32),
                                               "filter": "trilinear"}}}]}
    with pytest.raises(ValueError, match=r"texture data is empty \(shape \(0, 4, 3\)\)"):
        Scene.model_validate(d)
