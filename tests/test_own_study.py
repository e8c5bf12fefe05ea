"""A researcher's own study: the study file and own technique of docs/extending.md work from the command line,
study files are validated like scene files, and tables find the thesis's techniques by what they are."""
import csv
import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study_fixtures import write_scenes

README = (Path(__file__).parent.parent / "docs" / "extending.md").read_text()     # the examples a user copies


def _block(header: str, lang: str) -> str:
    section = README[README.index(header):]
    return re.search(rf"```{lang}\n(.*?)```", section, re.S).group(1)


def _invoke(args, code=0):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exit_code == code, r.output
    assert "Traceback" not in r.output
    return r


@pytest.fixture
def own(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    (tmp_path / "my_taa.py").write_text(_block("## Your own technique", "python"))
    moving, still = write_scenes(tmp_path)
    study = _block("## Your own study", "toml")
    study = study.replace('scenes = ["pipe", "sphere_ghosting"]', f'scenes = ["{Path(still).name}", "{Path(moving).name}"]')
    study = study.replace("resolution = [160, 90]", "resolution = [32, 18]")
    (tmp_path / "my_study.toml").write_text(study)
    return tmp_path


@pytest.mark.long(seconds=18)
def test_readme_study_file_and_own_technique_run(own, no_plots):
    _invoke(["run", own / "my_study.toml", "--precision", "per_pixel"])
    out = own / "out" / "my_study"
    summary = json.loads((out / "manifest.json").read_text())["summary"]
    assert summary["techniques"] == ["Uncharted", "Mine"]
    assert summary["scenes"] == [str(own / "tiny_still.toml"), str(own / "tiny_moving.toml")]
    head = list(csv.reader((out / "tables" / "headline.csv").read_text().splitlines()))
    assert head[0][:4] == ["scene", "protocol", "Uncharted", "Mine"]
    assert [r[1] for r in head[1:3]] == ["thesis (16 frames, cold)", "converged (64 frames)"]
    conv = (out / "tables" / "history_convergence.csv").read_text()
    assert "PSNR at 16 (thesis)" in conv and "tiny_still,Mine," in conv
    assert (out / "tables" / "ghosting_warm_tiny_moving.md").exists()
    assert not (out / "tables" / "ghosting_tiny_moving.md").exists()      # only the file's protocols

    # The widened box is a different technique; an edit of the file recomputes its runs only.
    s1 = summary
    (own / "my_taa.py").write_text((own / "my_taa.py").read_text() + "\n# an edit\n")
    _invoke(["run", own / "my_study.toml", "--precision", "per_pixel"])
    s2 = json.loads((out / "manifest.json").read_text())["summary"]
    assert s1["runs_computed"] == 6 and s2["runs_computed"] == 3 and s2["runs_cached"] == 3


def test_readme_ab_of_the_example_against_the_baseline(own):
    r = _invoke(["ab", "taa_baseline", f"Mine={own / 'my_taa.py'}:Box3x3TAA", "--study", own / "my_study.toml",
                 "--json"])
    res = json.loads(r.stdout)
    assert res["b"] == "Mine" and res["overall"]["psnr"]["n"] == 2 + 4    # 2 static frames + the moving scene's 4 frames
    assert res["overall"]["psnr"]["mean"] != 0                              # the clip box matters
    r = _invoke(["ab", "taa_baseline", f"{own / 'my_taa.py'}:Box3x3TAA:widen=2", "--study", own / "my_study.toml"],
                code=2)
    assert "widen must be in [0, 1], got 2" in r.output


def test_a_technique_whose_own_code_fails_exits_2_naming_it_its_file_and_line(own):
    """A bug in a researcher's technique file is their input: the study stops with its label, its
    file and class, the frame and the line that failed, never a traceback; no run is sealed, and the
    mended file's study goes through on the same cache."""
    src = (own / "my_taa.py").read_text().replace("return n.min3 - pad, n.max3 + pad, n.avg3", "return n.nothing")
    (own / "my_bad.py").write_text(src)
    line = src.splitlines().index("        return n.nothing") + 1
    r = _invoke(["ab", "taa_baseline", f"Bad={own / 'my_bad.py'}:Box3x3TAA", "--study", own / "my_study.toml",
                 "--no-video"], code=2)
    assert f"technique 'Bad' ({own / 'my_bad.py'}:Box3x3TAA) failed on scene 'tiny_" in r.output
    assert "frame 1 (step 0)" in r.output
    assert "AttributeError: 'Neighbourhood' object has no attribute 'nothing'" in r.output
    assert f"my_bad.py:{line})" in r.output
    assert not list((own / "cache" / "runs").rglob("done.json"))     # frames made before it: never sealed
    (own / "my_bad.py").write_text((own / "my_taa.py").read_text())   # mended, the same study goes through
    _invoke(["ab", "taa_baseline", f"Bad={own / 'my_bad.py'}:Box3x3TAA", "--study", own / "my_study.toml", "--no-video"])


@pytest.mark.parametrize("text, message", [
    ('name = ""', "field name"),
    ('name = "x"\nresolution = [4, 4]', "field resolution"),
    ('name = "x"\n[[techniques]]\nspec = "nosuch"', "field techniques[0]: unknown technique 'nosuch'"),
    ('name = "x"\n[[techniques]]\nspec = "taa_baseline:k_min=3"', "field techniques[0]"),
    ('name = "x"\n[protocols.static]\nhistory = 8\ncheckpoints = [4, 16]', "field protocols.static"),
    ('name = "x"\n[protocols.static]\nthesis_history = 5', "field protocols.static.thesis_history"),
    ('name = "x"\n[reference]\nspp = 4', "field reference.spp: unknown reference setting"),
    ('name = "x"\nsurprise = 1', "field surprise"),
    ('name = "x"\n[[protocols.ghosting]]\nname = "g"\nframes = 0', "field protocols.ghosting[0].frames"),
    ('name = = 1', "not valid TOML"),
    ('name = "x"\n[video]\ndisplay = "crt_1985"', "field video.display: unknown cvvdp display model"),
    ('name = "x"\n[video]\nfps = 0', "field video.fps"),
    ('name = "x"\n[video]\ntests = ["sweep"]', "field video.tests[0]"),
    ('name = "x"\n[video]\ntechniques = ["Nobody"]', "field video.techniques: names no column"),
    ('name = "x"\nrender_scale = [0.5, 2.0]', "field render_scale"),
    ('name = "x"\nrender_scale = [0.5, 0.5]', "render scales must be distinct"),
    ('name = "x"\nsharpen_sweep = [0, 5]', "field sharpen_sweep"),
    ('name = "x"\nsharpen_sweep = [0.5, 0.5]', "sharpen strengths must be distinct"),
    ('name = "x"\n[[techniques]]\nspec = "taa_baseline:sharpen=-1"', "sharpen strength must be in [0, 4]"),
    ('name = "x"\n[[techniques]]\nspec = "taa_baseline"\nrender_scale = 0.5',
     "field techniques[0]: render_scale is for a technique that upsamples"),
    ('name = "x"\n[[techniques]]\nspec = "taau"\nrender_scale = [0.05]', "render_scale must be in [0.1, 1]"),
])
def test_bad_study_files_exit_2_naming_file_field_and_value(tmp_path, text, message):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    r = _invoke(["run", f], code=2)
    assert message in r.output and str(f) in r.output


def test_reproduction_finds_the_thesis_techniques_whatever_their_labels(tmp_path, monkeypatch):
    from study.config.profile import thesis_roles
    from study.config.techniques import TechniqueConfig
    configs = [TechniqueConfig.parse(s) for s in ("Base=taa_baseline", "Imp=taa_improved",
                                                  "Imp sharp none=taa_improved:sharpen=none", "Plain=noaa")]
    assert thesis_roles(configs) == {"No AA": "Plain", "Uncharted": "Base", "Improved": "Imp"}
    assert thesis_roles([TechniqueConfig.parse("X=taa_improved:sharpen=none")]) == {}


def test_a_technique_from_an_installed_package_entry_point(tmp_path, monkeypatch):
    """An installed distribution declaring [taa_study.techniques] is found by name."""
    (tmp_path / "my_aa_pkg.py").write_text(
        "from taa_impl.simple import NoAA\nclass Centre(NoAA):\n    name = 'centre_ep'\n")
    info = tmp_path / "my_aa_pkg-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-aa-pkg\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[taa_study.techniques]\ncentre_ep = my_aa_pkg:Centre\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    from provenance import code_token
    from study.config.techniques import TechniqueConfig, resolve_technique
    cls = resolve_technique("centre_ep")
    assert cls.__name__ == "Centre" and TechniqueConfig.parse("centre_ep").make().name == "centre_ep"
    assert "my_aa_pkg" in TechniqueConfig.parse("centre_ep").key_data()["class"]
    assert code_token(cls)          # its own source is keyed
    with pytest.raises(ValueError, match="not an entry point of 'taa_study.techniques'"):
        resolve_technique("centre_nope")


def test_a_study_files_render_scales_make_one_column_per_upscaler_and_scale(tmp_path):
    from study.config.studyfile import load_study
    from study.config.techniques import family, render_scale
    f = tmp_path / "ups.toml"
    f.write_text('name = "u"\nrender_scale = [0.5, 0.67, 1.0]\n'
                 '[[techniques]]\nspec = "Uncharted=taa_baseline"\n'
                 '[[techniques]]\nspec = "FSR 2=fsr2"\n'
                 '[[techniques]]\nspec = "T=taau:render_scale=0.77"\n'
                 '[[techniques]]\nlabel = "L"\ntechnique = "upscale_spatial"\nrender_scale = 0.5\n')
    cs = load_study(f).techniques
    assert [c.label for c in cs] == ["Uncharted", "FSR 2 ×0.5", "FSR 2 ×0.67", "FSR 2 ×1", "T", "L ×0.5"]
    assert [render_scale(c) for c in cs] == [1.0, 0.5, 0.67, 1.0, 0.77, 0.5]
    assert [family(c) for c in cs] == ["Uncharted", "FSR 2", "FSR 2", "FSR 2", "T", "L"]
    assert cs[1].make().inputs.jitter_period == 32 and cs[3].make().inputs.jitter_period == 8


def test_ab_refuses_a_bad_render_scale_and_one_for_techniques_that_do_not_upsample():
    r = _invoke(["ab", "taa_baseline", "taau", "--render-scale", "0.5,3"], code=2)
    assert "--render-scale '0.5,3'" in r.output and "[0.1, 1]" in r.output
    r = _invoke(["ab", "taa_baseline", "noaa", "--render-scale", "0.5"], code=2)
    assert "neither 'taa_baseline' nor 'noaa' upsamples" in r.output
