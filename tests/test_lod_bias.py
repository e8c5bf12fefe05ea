"""A study column's texture LOD bias (study.config.techniques.lod_bias): its default rule, the
study file's limit, and raster frames shared between columns only where the bias cannot matter."""
import math

import numpy as np
import pytest

from scenes.description import Scene
from scenes.resolved import ResolvedScene
from study.config.protocols import static_schedule
from study.config.studyfile import StudyFileError, load_study
from study.config.techniques import TechniqueConfig as TC
from study.config.techniques import lod_bias
from study.engine import drive


def test_default_bias_is_fsr2s_rule_for_temporal_upscalers_the_density_for_spatial_ones_zero_else():
    assert lod_bias(TC("FSR 2", "fsr2", (("render_scale", 0.5),))) == pytest.approx(-2.0)
    assert lod_bias(TC("TAAU", "taau", (("render_scale", 0.75),))) == pytest.approx(math.log2(0.75) - 1)
    assert lod_bias(TC("Lanczos", "upscale_spatial", (("render_scale", 0.5),))) == pytest.approx(-1.0)
    assert lod_bias(TC("TAA", "taa_baseline")) == 0.0 and lod_bias(TC("FXAA", "fxaa")) == 0.0
    assert lod_bias(TC("TAA", "taa_baseline", (), -1.25)) == -1.25
    assert "lod_bias" not in TC("TAA", "taa_baseline").key_data()     # default columns keep their keys
    assert TC("TAA", "taa_baseline", (), -1.0).key_data()["lod_bias"] == -1.0


def _study(tmp_path, body: str):
    p = tmp_path / "s.toml"
    p.write_text('name = "s"\nscenes = ["pipe"]\n' + body)
    return p


def test_a_bias_beyond_the_limit_or_not_finite_is_refused_naming_file_field_and_value(tmp_path):
    p = _study(tmp_path, '[[techniques]]\ntechnique = "taa_baseline"\nlod_bias = -4.5\n')
    with pytest.raises(StudyFileError, match=r"s\.toml: field techniques\[0\]\.lod_bias: .*min_lod_bias = -4 \(value: -4\.5\)"):
        load_study(p)
    p = _study(tmp_path, '[[techniques]]\ntechnique = "taa_baseline"\nlod_bias = nan\n')
    with pytest.raises(StudyFileError, match=r"techniques\[0\]\.lod_bias.*nan"):
        load_study(p)
    # the upscalers' rule is held to the limit too: render scale 0.1 gives log2(0.1) - 1 = -4.32
    p = _study(tmp_path, '[[techniques]]\nspec = "U=taau"\nrender_scale = 0.1\n')
    with pytest.raises(StudyFileError, match=r"techniques\[0\]\.lod_bias.*upscalers' rule"):
        load_study(p)
    p = _study(tmp_path, 'min_lod_bias = -5.0\n[[techniques]]\ntechnique = "taa_baseline"\nlod_bias = -4.5\n')
    assert load_study(p).techniques[0].lod_bias == -4.5


def _floor(filt: str):
    rng = np.random.default_rng(4)
    d = {"name": f"floor_{filt}", "transport": "unlit", "camera": {"position": [0, 0.3, 1], "target": [0, 0, -1]},
         "objects": [{"name": "p", "mesh": {"kind": "plane", "size": [4.0, 4.0, 1.0], "uv_scale": [3.0, 3.0]},
                      "material": {"texture": {"kind": "array", "data": rng.random((64, 64, 3)).astype(np.float32),
                                               "filter": filt}},
                      "transform": {"rotate_axis": [1, 0, 0], "rotate_deg": -90.0}}]}
    return ResolvedScene(Scene.model_validate(d))


@pytest.mark.parametrize("filt,sources", [("trilinear", 2), ("nearest", 1), ("bilinear", 1)])
def test_columns_of_different_biases_share_frames_only_where_no_texture_is_trilinear(filt, sources, monkeypatch):
    made = []
    real = drive.FrameSource.__init__

    def spy(self, *a, **kw):
        made.append(kw.get("lod_bias", a[5] if len(a) > 5 else 0.0))
        real(self, *a, **kw)
    monkeypatch.setattr(drive.FrameSource, "__init__", spy)
    cfgs = [TC("sharp", "noaa", (), -2.0), TC("plain", "noaa"), TC("plain too", "noaa", (), 0.0)]
    out = drive.run_schedule(_floor(filt), 32, 18, static_schedule(0, 1, [1]), cfgs, {}, progress=False)
    assert len(made) == sources
    sharp, plain, same = (out[c.label]["images"][1] for c in cfgs)
    assert np.array_equal(plain, same)
    assert np.array_equal(sharp, plain) == (filt != "trilinear")


def test_the_command_lines_spec_form_sets_the_bias_and_refuses_a_bad_one(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from study.commands.cli import main
    c = TC.parse("Sharp=taa_baseline:sharpen=0.2,lod_bias=-1.5")
    assert (c.lod_bias, c.overrides) == (-1.5, (("sharpen", 0.2),))
    with pytest.raises(ValueError, match="lod_bias must be a finite number"):
        TC.parse("S=taa_baseline:lod_bias=NaN")
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(main, ["run", "--scenes", "pipe", "--techniques", "S=taa_baseline:lod_bias=-6"])
    assert r.exit_code == 2 and "lod_bias -6 is more negative than -4" in r.output, r.output
    assert not any(tmp_path.iterdir())          # nothing written
