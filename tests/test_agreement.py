"""The raster and the reference agree (foundation issue), on small versions of built-in scenes
that between them have a moving object, a texture, shadows and an alpha cut-out."""
import json

import pytest
from click.testing import CliRunner

from references import ReferenceCache
from scenes import get_scene
from study.engine.agreement import TARGETS, check_agreement
from study.commands.cli import main


@pytest.mark.long(seconds=10)     # flowers about 25 s, the others 2
@pytest.mark.parametrize("name,frame", [("sphere_ghosting", 7), ("text_wall", 0), ("flowers", 0)])
def test_agreement_targets_on_small_builtin_scenes(name, frame, tmp_path):
    scene = get_scene(name)
    a = check_agreement(scene, 96, 54, frame=frame, samples=128, cache=ReferenceCache(tmp_path),
                        progress=False)
    assert a.agreement_psnr_db >= TARGETS["agreement_psnr_db"]
    assert a.interior_max_abs_err <= TARGETS["interior_max_abs_err"]
    assert a.reference_noise_psnr_db >= TARGETS["reference_noise_psnr_db"]
    assert a.single_sample and a.centre_match_fraction > 0.99
    assert a.interior_pixels > 0.5 * 96 * 54


def test_cli_agree_json_keys_and_scene_listing(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path))
    r = CliRunner().invoke(main, ["agree", "--scene", "atrium", "--width", "64", "--height", "36",
                                  "--samples", "64", "--json"])
    assert r.exit_code in (0, 1), r.output
    out = json.loads(r.output)
    for key in ("agreement_psnr_db", "interior_max_abs_err", "reference_noise_psnr_db", "single_sample",
                "reference_spp", "raster_samples"):
        assert key in out
    assert out["raster_samples"] == 64 and out["single_sample"] is True
    r = CliRunner().invoke(main, ["scenes", "--json"])
    rows = json.loads(r.output)
    assert {"name", "frames", "width", "height", "features"} <= set(rows[0])
    assert any("alpha_cutout" in row["features"] for row in rows)


def test_cli_bad_scene_file_exits_nonzero_naming_the_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\n[camera]\nposition = [0, 0, 1]\ntarget = [0, 0, 0]\nyfov_deg = 500\n'
                   '[[objects]]\nname = "o"\nmesh = { kind = "box" }\n')
    r = CliRunner().invoke(main, ["agree", "--scene", str(bad)])
    assert r.exit_code == 2
    assert "bad.toml" in r.output and "camera.yfov_deg" in r.output and "500" in r.output
