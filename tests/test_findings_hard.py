"""The findings on today's hard cases (study.reporting.findings_hard): from hand-made ghosting
results, each column's temporal RMS against No AA's and the baseline's, its PSNR and FLIP cost, and
the sentences the findings print."""
import math

import pytest

from study.engine.results import StudyResults
from study.engine.results import TestResult as Result
from study.reporting import findings as F
from study.reporting import findings_hard as H
from study.reporting import findings_text as FT

ROLES = {"No AA": "No AA", "FXAA": "FXAA", "Uncharted": "Uncharted", "Improved": "Improved"}
TECH = {"No AA": "noaa", "FXAA": "fxaa", "Uncharted": "taa_baseline", "Improved": "taa_improved",
        "Tonemap": "taa_tonemap_blend", "U none": "taa_baseline"}


def ghost(scene, temporal, psnr, flip, u=0.0, frames=(0, 1)):
    """A ghosting result: label -> temporal RMS, label -> per-frame PSNR (one per frame), FLIP."""
    per = {l: {t: {"psnr": psnr[l][i], "flip_ldr": flip[l], "mse": 1.0} for i, t in enumerate(frames)} for l in psnr}
    g = Result(scene, "ghosting", list(frames), per, {l: 1.0 for l in psnr}, kind="ghosting", width=320, height=180)
    g.uncertainty = {l: {t: {"psnr": 0.01 * (i + 1), "flip_ldr": 1e-4} for i, t in enumerate(frames)} for l in psnr}
    g.temporal, g.temporal_u = dict(temporal), {l: u for l in temporal}
    g.artefacts = {l: {"technique": TECH[l], "overrides": [["sharpen", "none"]] if l == "U none" else []}
                   for l in psnr}
    return g


def _two_scenes(u=0.0):
    a = ghost("specular_shimmer", {"No AA": 4.0, "FXAA": 3.0, "Uncharted": 2.0, "Tonemap": 1.0},
              {"No AA": [30.0, 32.0], "FXAA": [31.0, 31.0], "Uncharted": [33.0, 33.0], "Tonemap": [32.0, 32.0]},
              {"No AA": 0.20, "FXAA": 0.18, "Uncharted": 0.15, "Tonemap": 0.16}, u=u)
    b = ghost("texture_crawl", {"No AA": 2.0, "FXAA": 2.5, "Uncharted": 1.0, "Tonemap": 1.5},
              {"No AA": [20.0, 20.0], "FXAA": [20.0, 20.0], "Uncharted": [22.0, 22.0], "Tonemap": [21.0, 21.0]},
              {"No AA": 0.30, "FXAA": 0.30, "Uncharted": 0.25, "Tonemap": 0.27}, u=u)
    pipe = ghost("pipe", {"No AA": 9.0, "FXAA": 9.0, "Uncharted": 9.0, "Tonemap": 9.0},
                 {l: [1.0, 1.0] for l in TECH if l != "U none"}, {l: 0.5 for l in TECH if l != "U none"})
    return StudyResults(views={}, ghosts={"ghosting": [a, b, pipe]})


def test_the_hard_case_scenes_are_those_of_the_modern_library():
    assert set(H.hard_case_scenes()) == {"specular_shimmer", "specular_rail", "texture_crawl", "foliage_sway",
                                         "modern_mix"}


def test_each_column_s_flicker_and_blur_cost_are_computed_from_the_figures():
    (f,) = H.hard_cases(_two_scenes(), ROLES)
    assert f["scenes"] == ["specular_shimmer", "texture_crawl"] and f["protocol"] == "ghosting"   # pipe is none
    fx = f["columns"]["FXAA"]["vs_no_aa"]
    # ratios 3/4 and 2.5/2; PSNR (31 - 31) and (20 - 20); FLIP -0.02 and 0
    assert fx["ratio"] == {"mean": pytest.approx((0.75 + 1.25) / 2), "min": pytest.approx(0.75),
                           "max": pytest.approx(1.25), "n": 2}
    assert fx["psnr"]["mean"] == pytest.approx(0.0) and fx["flip"]["mean"] == pytest.approx(-0.01)
    assert (fx["steadier"], fx["unsteadier"], fx["of"]) == (1, 1, 2)
    tm = f["columns"]["Tonemap"]
    assert "vs_uncharted" in tm and "vs_uncharted" not in f["columns"]["Uncharted"]
    assert tm["vs_uncharted"]["ratio"]["mean"] == pytest.approx((0.5 + 1.5) / 2)
    assert tm["vs_uncharted"]["psnr"]["mean"] == pytest.approx(-1.0)
    assert tm["vs_uncharted"]["flip"]["mean"] == pytest.approx((0.01 + 0.02) / 2)
    assert tm["vs_no_aa"]["psnr"]["mean"] == pytest.approx((1.0 + 1.0) / 2)
    # the reference uncertainty decides "steadier": 0.3 each side makes FXAA's 3.0 against 4.0 a tie
    fu = H.hard_cases(_two_scenes(u=0.3), ROLES)[0]["columns"]["FXAA"]["vs_no_aa"]
    assert (fu["steadier"], fu["unsteadier"]) == (1, 0)
    fu = H.hard_cases(_two_scenes(u=0.6), ROLES)[0]["columns"]["FXAA"]["vs_no_aa"]
    assert (fu["steadier"], fu["unsteadier"]) == (0, 0)


def test_the_sentences_state_the_figures_and_the_findings_carry_them():
    res = _two_scenes()
    rec = F.findings(res, ROLES, {})
    hard = next(f for f in rec["factors"] if f["id"] == "hard_cases")
    lines = H.sentences(hard)
    assert len(lines) == 1 + 3                  # the lead, then FXAA, Uncharted, Tonemap
    # steadiest first by the mean ratio: Uncharted and Tonemap (0.5 each, in the columns' order), FXAA (1.0)
    assert [l.split(":")[0] for l in lines[1:]] == ["Uncharted", "Tonemap", "FXAA"]
    assert "steadiest first: Uncharted, Tonemap;" in lines[0]
    # a mean's uncertainty: sqrt(0.01^2 + 0.02^2) / 2 dB, sqrt(2) 1e-4 / 2 FLIP
    assert hard["mean_u"] == {"psnr": pytest.approx(math.hypot(0.01, 0.02) / 2),
                              "flip_ldr": pytest.approx(math.sqrt(2) * 1e-4 / 2)}
    assert lines[0].endswith("(means over the frames, each within ±0.011 dB PSNR and ±0.0001 FLIP of the "
                             "reference's uncertainty).")
    assert lines[3].startswith("FXAA: temporal RMS 1.00 (0.75 to 1.25) times No AA's (steadier than No AA on 1 of "
                               "2 scenes, less steady on 1), at +0.00 (+0.00 to +0.00) dB PSNR and -0.010 (-0.020 "
                               "to +0.000) FLIP against it.")
    assert ("Karis 2014's tonemapped blend on the baseline TAA: temporal RMS 1.00 (0.50 to 1.50) times Uncharted's"
            in lines[2] and "at -1.00 (-1.00 to -1.00) dB PSNR" in lines[2])
    summary = FT.summary(rec)
    assert all(l in summary for l in lines)
    assert " ".join(lines) == FT.factor_sentence(hard)
    assert lines[0].startswith("On today's hard cases (2 scenes, 320x180; ghosting: specular_shimmer, texture_crawl)")


def test_each_ghosting_protocol_of_the_hard_cases_gets_its_own_record():
    res = _two_scenes()
    warm = _two_scenes().ghosts["ghosting"][:1]
    warm[0].temporal = {**warm[0].temporal, "Uncharted": 1.0}
    res.ghosts["ghosting_warm"] = warm
    cold, hot = H.hard_cases(res, ROLES)
    assert (cold["protocol"], hot["protocol"]) == ("ghosting", "ghosting_warm") and hot["scenes"] == ["specular_shimmer"]
    assert hot["columns"]["Uncharted"]["vs_no_aa"]["ratio"]["mean"] == pytest.approx(0.25)
    rec = F.findings(res, ROLES, {})
    assert [f["protocol"] for f in rec["factors"] if f["id"] == "hard_cases"] == ["ghosting", "ghosting_warm"]


def test_the_baseline_with_its_own_parameters_is_judged_against_the_baseline_too():
    res = _two_scenes()
    g = res.ghosts["ghosting"][0]
    l = "U none"
    g.per_frame[l] = {t: {"psnr": 34.0, "flip_ldr": 0.14} for t in g.frames}
    g.temporal[l], g.temporal_u[l], g.artefacts[l] = 1.5, 0.0, {"technique": "taa_baseline", "overrides": [["sharpen", "none"]]}
    c = H.hard_cases(res, ROLES)[0]["columns"][l]
    assert c["preset"] == "the baseline TAA with sharpen = none" and c["scenes"] == ["specular_shimmer"]
    assert c["vs_uncharted"]["ratio"]["mean"] == pytest.approx(0.75) and c["vs_uncharted"]["psnr"]["mean"] == pytest.approx(1.0)
    line = next(s for s in H.sentences(H.hard_cases(res, ROLES)[0]) if s.startswith(l))
    assert "; the baseline TAA with sharpen = none: temporal RMS 0.75 times Uncharted's" in line


def test_no_hard_case_ghosting_test_makes_no_record():
    res = _two_scenes()
    res.ghosts["ghosting"] = res.ghosts["ghosting"][2:]
    assert H.hard_cases(res, ROLES) == []
    assert not any(f["id"] == "hard_cases" for f in F.findings(res, ROLES, {})["factors"])


def test_a_missing_figure_is_left_out_not_spread():
    res = _two_scenes()
    res.ghosts["ghosting"][0].temporal["FXAA"] = math.nan
    fx = H.hard_cases(res, ROLES)[0]["columns"]["FXAA"]["vs_no_aa"]
    assert fx["ratio"] == {"mean": pytest.approx(1.25), "min": pytest.approx(1.25), "max": pytest.approx(1.25), "n": 1}
