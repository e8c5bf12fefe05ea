"""A study file's scene groups ([[scene_groups]]): scenes tested only under their own protocols with
their own columns, their figures exempt where the file says so; bad groups exit 2 naming the field."""
import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study.config.precision import EXEMPTABLE, Exemption, Precision
from study.config.studyfile import load_study, profile
from study.engine.runner import Study

HARD = ("specular_shimmer", "specular_rail", "texture_crawl", "foliage_sway", "modern_mix")


def test_the_figures_an_exemption_names_are_those_with_a_tolerance():
    from study.metrics.uncertainty import TOLERANCE_OF
    # each frame's figure, the temporal RMS, and a ghosting test's mean over frames of each
    per_frame = set(TOLERANCE_OF) - {"temporal"}
    assert set(EXEMPTABLE) == set(TOLERANCE_OF) | {m + "_mean" for m in per_frame}


def test_an_exemption_covers_its_column_s_figures_on_its_tests_and_scenes_only():
    p = Precision(exempt=("Accumulation 128",),
                  exemptions=(Exemption("FXAA", ("mse", "temporal"), ("ghosting",), ("moire", "/s/my.toml")),))
    assert p.exempts("moire", "ghosting", "FXAA", "temporal")
    assert p.exempts("/s/./my.toml", "ghosting", "FXAA", "mse")        # a scene file by its resolved path
    assert not p.exempts("moire", "ghosting", "FXAA", "psnr")
    assert not p.exempts("moire", "ghosting_warm", "FXAA", "mse")
    assert not p.exempts("pipe", "ghosting", "FXAA", "mse")
    assert not p.exempts("moire", "ghosting", "No AA", "mse")
    assert p.exempts("pipe", "static", "Accumulation 128", "psnr")     # a whole column, as before
    assert Exemption("FXAA").covers("pipe", "static", "FXAA", "ssim")  # empty lists: every one
    assert Exemption(None, ("ssim",)).covers("pipe", "static", "Mine", "ssim")     # no column: every one
    assert not Exemption(None, ("ssim",)).covers("pipe", "static", "Mine", "temporal")


def test_the_quick_profile_tests_the_hard_cases_warm_with_the_flicker_columns():
    p = profile("quick")
    assert set(HARD) <= set(p.scenes)
    g, moving = p.scene_groups
    assert set(g.scenes) == set(HARD) and g.tests == ("ghosting_warm",)
    # the moving scenes but the sphere: in motion alone, every column
    assert moving.tests == ("ghosting", "ghosting_warm") and "sphere_ghosting" not in moving.scenes
    assert moving.configs(p.techniques, own=True) == list(p.techniques)
    labels = [c.label for c in g.configs(p.techniques, own=True)]
    assert labels[:4] == ["No AA", "FXAA", "Uncharted", "Improved"]
    assert [c.name for c in g.techniques] == ["taa_tonemap_blend", "taa_variance", "taa_ycocg", "fsr2"]
    from study.config.techniques import lod_bias
    import math
    assert lod_bias(g.techniques[-1]) == pytest.approx(math.log2(0.67) - 1)
    ex = p.precision
    # the per-frame figures of every column set no bound there; the temporal RMS does, but FXAA's
    assert all(ex.exempts(s, "ghosting_warm", c, f) for s in HARD for c in labels
               for f in ("mse", "psnr", "ssim", "flip_ldr"))
    assert ex.exempts("modern_mix", "ghosting_warm", "FXAA", "temporal")
    assert not any(ex.exempts(s, "ghosting_warm", c, "temporal") for s in HARD for c in labels if c != "FXAA")
    assert not ex.exempts("moire", "ghosting", "FXAA", "temporal")                  # the other scenes as before
    cols = [c.label for c in p.techniques if c.label not in ("Accumulation 128", "SSAA 16x")]   # the controls: exempt
    assert not any(ex.exempts("pipe", "static", c, f) for c in cols for f in EXEMPTABLE)
    # a ghosting test anywhere: each frame's figures set no bound, their means and the temporal RMS do
    assert all(ex.exempts(s, t, c, f) for s in ("pipe", "sphere_ghosting") for t in ("ghosting", "ghosting_warm")
               for c in cols for f in ("mse", "psnr", "ssim", "flip_ldr"))
    assert not any(ex.exempts("sphere_ghosting", "ghosting", c, f) for c in cols
                   for f in ("mse_mean", "psnr_mean", "ssim_mean", "flip_ldr_mean", "temporal"))
    # a run given other columns keeps them on the group's scenes too
    assert g.configs(p.techniques[:2], own=False) == list(p.techniques[:2])


def test_the_plan_gives_a_group_s_scenes_only_its_tests_and_columns(tmp_path):
    p = profile("quick")
    study = Study(p, cache_root=tmp_path, progress=False)
    _, _, statics, ghosts, _, _ = study.plan(["sphere_ghosting", "specular_shimmer"], list(p.techniques),
                                             agreement=False)
    assert [t.scene for t in statics] == ["sphere_ghosting"]
    by = {(t.scene, t.protocol.name): [c.label for c in t.configs] for t in ghosts}
    assert set(by) == {("sphere_ghosting", "ghosting"), ("sphere_ghosting", "ghosting_warm"),
                       ("specular_shimmer", "ghosting_warm")}
    assert by[("specular_shimmer", "ghosting_warm")] == [c.label for c in p.scene_groups[0].configs(p.techniques, True)]
    skip = p.ghosting_techniques_skip
    assert by[("sphere_ghosting", "ghosting")] == [c.label for c in p.techniques
                                                   if c.label not in skip and c.name not in skip]


def _invoke(args, code=0):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exit_code == code, r.output
    assert "Traceback" not in r.output
    return r


GROUP = 'name = "x"\nscenes = ["pipe", "moire"]\n[[techniques]]\nspec = "No AA=noaa"\n[[techniques]]\nspec = "FXAA=fxaa"\n'


@pytest.mark.parametrize("text, message", [
    ('[[scene_groups]]\nname = "g"\nscenes = ["atrium"]', "field scene_groups[0].scenes[0]: names no scene of the "
     "study's scenes (value: 'atrium')"),
    ('[[scene_groups]]\nname = "g"\nscenes = []', "field scene_groups[0].scenes"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\ntests = ["ghost"]', "field scene_groups[0].tests[0]: names "
     "no test of the study; known: static, ghosting (value: 'ghost')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\ncolumns = ["SMAA"]', "field scene_groups[0].columns[0]: "
     "names no column of the study's [[techniques]] (a label) (value: 'SMAA')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups.techniques]]\nspec = "nosuch"',
     "field scene_groups[0].techniques[0]: unknown technique 'nosuch'"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups.techniques]]\nspec = "FXAA=taa_variance"',
     "field scene_groups[0].techniques: labels must be unique among the study's columns and the group's "
     "(value: 'FXAA')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups]]\nname = "h"\nscenes = ["moire"]',
     "field scene_groups[1].scenes[0]: is in group 'g' too (value: 'moire')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups]]\nname = "g"\nscenes = ["pipe"]',
     "field scene_groups[1].name: names another group too (value: 'g')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\ncolumns = ["No AA"]\n[[scene_groups.exempt]]\n'
     'column = "FXAA"', "field scene_groups[0].exempt[0].column: names no column of the study (its labels) "
     "(value: 'FXAA')"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups.exempt]]\ncolumn = "FXAA"\nfigures = ["mes"]',
     "field scene_groups[0].exempt[0].figures: unknown figure 'mes'"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\n[[scene_groups.exempt]]\ncolumn = ""',
     "field scene_groups[0].exempt[0].column"),
    ('[[scene_groups]]\nname = "g"\nscenes = ["moire"]\ntests = ["ghosting"]\n[[scene_groups.exempt]]\n'
     'column = "FXAA"\ntests = ["static"]', "field scene_groups[0].exempt[0].tests[0]: names no test of the study; "
     "known: ghosting (value: 'static')"),
    ('[precision]\nexempt = ["No AA", {column = "TAA"}]', "field precision.exempt[1].column: names no column"),
    ('[precision]\nexempt = [{column = "FXAA", scenes = ["atrium"]}]', "field precision.exempt[0].scenes[0]: names "
     "no scene of the study's scenes (value: 'atrium')"),
])
def test_bad_scene_groups_exit_2_naming_the_field_and_value(tmp_path, text, message):
    f = tmp_path / "bad.toml"
    f.write_text(GROUP + text)
    r = _invoke(["run", f], code=2)
    assert message in r.output and str(f) in r.output


def test_a_group_s_exemptions_and_precision_s_tables_reach_the_precision(tmp_path):
    f = tmp_path / "ok.toml"
    f.write_text(GROUP + '[[scene_groups]]\nname = "g"\nscenes = ["moire"]\ntests = ["ghosting"]\n'
                 '[[scene_groups.exempt]]\ncolumn = "FXAA"\nfigures = ["temporal"]\n[[scene_groups.exempt]]\n'
                 'figures = ["ssim"]\ntests = ["ghosting"]\n'
                 '[precision]\nexempt = ["No AA", {column = "FXAA", figures = ["ssim"], scenes = ["pipe"]}]\n')
    p = load_study(f).precision
    assert p.exempt == ("No AA",)
    assert p.exemptions == (Exemption("FXAA", ("temporal",), (), ("moire",)),
                            Exemption(None, ("ssim",), ("ghosting",), ("moire",)),
                            Exemption("FXAA", ("ssim",), (), ("pipe",)))


@pytest.mark.long(seconds=12)
def test_a_study_whose_scenes_have_no_static_test_ends_with_its_summary(tmp_path, monkeypatch, reference_pool):
    """Every scene in a group that runs only a ghosting test: no headline table is written, and the
    run says so and exits 0 (it read tables/headline.md and ended in a traceback)."""
    import json
    from study_fixtures import write_scenes
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    reference_pool.seed(tmp_path / "cache")
    moving, _ = write_scenes(tmp_path)
    f = tmp_path / "g.toml"
    f.write_text(f'name = "g"\nscenes = [{json.dumps(moving)}]\nresolution = "quick"\nagreement = false\n'
                 'sweep = false\n[[techniques]]\nspec = "noaa"\n[protocols.static]\nhistory = 4\ncheckpoints = [4]\n'
                 'thesis_history = 4\n[[protocols.ghosting]]\nname = "ghosting"\nframes = 3\nwarmup = 0\n'
                 '[video]\nmetric = "none"\n[precision]\nrule = "per_pixel"\n[reference]\nse_bound_lsb = 8.0\n'
                 f'[[scene_groups]]\nname = "moving"\nscenes = [{json.dumps(moving)}]\ntests = ["ghosting"]\n')
    r = _invoke(["run", f, "--out", tmp_path / "out"])
    reference_pool.keep(tmp_path / "cache")
    assert "no static test here, so no headline table" in r.output and "runs computed" in r.output
    assert (tmp_path / "out" / "report.html").exists() and not (tmp_path / "out" / "tables" / "headline.md").exists()


def test_a_group_s_tests_are_checked_against_the_protocols_with_reuse_on_some_scenes(tmp_path):
    """reference.reuse's list of scenes once replaced the protocol names a group's tests are checked
    against: a valid group was refused, and a group naming a scene as its test accepted."""
    f = tmp_path / "s.toml"
    body = ('name = "x"\nscenes = ["pipe", "sphere_ghosting"]\n[reference]\nreuse = ["sphere_ghosting"]\n'
            '[[techniques]]\nspec = "noaa"\n[[scene_groups]]\nname = "g"\nscenes = ["sphere_ghosting"]\n')
    f.write_text(body + 'tests = ["ghosting"]\n')
    assert load_study(f).scene_groups[0].tests == ("ghosting",)
    f.write_text(body + 'tests = ["sphere_ghosting"]\n')
    r = _invoke(["estimate", f], code=2)
    assert "scene_groups[0].tests[0]" in r.output and "'sphere_ghosting'" in r.output
