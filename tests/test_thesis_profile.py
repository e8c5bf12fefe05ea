"""The thesis profile (`make thesis`): Oliveros 2018's scenes, resolution, protocols and columns, and
what its findings need to state causes; planned and estimated, nothing rendered."""
import json

import pytest
from click.testing import CliRunner

from scenes import get_scene
from study.commands.cli import main
from study.config.profile import get_profile, thesis_roles
from study.engine.runner import is_animated
from study.reporting import ground_truth
from study.reporting.findings import sharpen_variants
from study.reporting.thesis import THESIS_COLUMNS, THESIS_GHOST_MSE, THESIS_STATIC_PSNR

STATIC = ["pipe", "pipe_tilted", "blinds", "arched_window", "atrium", "flowers", "hard_edges", "hairball_unlit",
          "hairball_lit"]
GHOSTING = ["sphere_ghosting", "hairball_rotating_unlit", "hairball_rotating_lit"]
SWAPPED = ["Uncharted, normalised sharpen", "Improved, Xu sharpen"]


def test_the_thesis_profile_is_the_thesis_s_study():
    p = get_profile("thesis")
    assert list(p.scenes) == STATIC + GHOSTING
    # the scenes of the thesis's tables, and which of them move
    assert set(STATIC) == set(THESIS_STATIC_PSNR) and set(GHOSTING) == set(THESIS_GHOST_MSE)
    assert [is_animated(get_scene(s)) for s in p.scenes] == [False] * 9 + [True] * 3
    assert p.resolution == (1600, 900)
    # its protocol (16 frames, cold) and the converged control, from one 256-frame run
    assert (p.static.history, p.static.checkpoints, p.thesis_history) == (256, (16, 256), 16)
    assert p.static_views == {"thesis (16 frames, cold)": 16, "converged (256 frames)": 256}
    assert [(g.name, g.frames, g.warmup) for g in p.ghosting] == [("ghosting", 100, 0), ("ghosting_warm", 100, 224)]
    labels = [c.label for c in p.techniques]
    assert labels[:5] == list(THESIS_COLUMNS) == ["No AA", "FXAA", "SMAA", "Uncharted", "Improved"]
    assert thesis_roles(p.techniques) == {c: c for c in THESIS_COLUMNS}
    # what the findings' causes read: both TAAs with each kernel (their own, the other's, none), the
    # thesis's ground truth, the sharpen sweep on every static scene; nothing else
    assert sorted(sharpen_variants(p.techniques).values()) == sorted(
        ["Uncharted", "Improved", "Uncharted, no sharpen", "Improved, no sharpen", *SWAPPED])
    assert ground_truth.label_of(p.techniques) == "Accumulation 128"
    assert len(labels) == 10 and not p.sweep and not p.video.on
    assert p.sharpen_sweep and set(STATIC) <= set(p.sharpen_sweep_scenes)
    # the swapped kernels and the ground truth are judged in the static test alone (as the thesis did)
    assert set(p.ghosting_techniques_skip) == {*SWAPPED, "Accumulation 128"}
    assert p.agreement
    # references reuse the previous frame's pixels on sphere_ghosting alone (where it pays)
    assert dict(p.ref_settings)["reuse"] == ("sphere_ghosting",)
    # a ghosting test bound by its means over the 100 frames and its temporal RMS; static by every figure
    ex = p.precision
    for c in labels[:5]:
        assert all(ex.exempts(s, t, c, f) for s in GHOSTING for t in ("ghosting", "ghosting_warm")
                   for f in ("mse", "psnr", "ssim", "flip_ldr"))
        assert not any(ex.exempts(s, "ghosting", c, f) for s in GHOSTING for f in ("mse_mean", "psnr_mean", "temporal"))
        assert not any(ex.exempts(s, "static", c, f) for s in STATIC for f in ("mse", "psnr", "ssim", "flip_ldr"))


@pytest.mark.long(seconds=15)
def test_estimate_plans_the_thesis_study_and_its_peak_disk(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    r = CliRunner().invoke(main, ["estimate", "--profile", "thesis", "--json"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    # references: each static scene's frame 0, each ghosting scene's 100 instants (frame 0 shared)
    # no static test on the ghosting scenes (their scene group): 9 static + 6 ghosting + 9 sharpen runs
    assert doc["tasks"] == {"reference": 9 + 300, "run": 24, "metrics": 24, "agreement": 12}
    rows = {row["scene"]: row for row in doc["scenes"]}
    assert list(rows) == STATIC + GHOSTING and all(row["resolution"] == [1600, 900] for row in rows.values())
    sweep = 2 * len(get_profile("thesis").sharpen_sweep)      # both TAAs at each strength, 16 frames
    for s in STATIC:
        # 6 TAA columns x 256 frames, No AA / FXAA / SMAA / Accumulation 128 once, the sweep's 16 frames
        assert rows[s]["technique_steps"] == 6 * 256 + 4 + sweep * 16
        # the TAAs at 16 and 256 frames, the rest once, the sweep at 16
        assert rows[s]["technique_frames_judged"] == 6 * 2 + 4 + sweep
        assert rows[s]["references"] == 1 and rows[s]["agreement_frames"] == 257
    for s in GHOSTING:
        # cold: 7 columns x 100 + warm: the 4 TAAs x (224 + 100) (a column without history sees the
        # same frames warm as cold: its run is shared)
        assert rows[s]["technique_steps"] == 7 * 100 + 4 * 324
        assert rows[s]["technique_frames_judged"] == 7 * 100 + 4 * 100
        assert rows[s]["references"] == 100
    d = doc["disk"]
    assert d["peak_gb"] > d["least_gb"] > d["references_gb"] + d["maps_gb"] + d["runs_kept_gb"]
    # superseded references removed as it refines, the probe's too (their display transforms kept as
    # records): one round's references at a time
    assert d["superseded"] == "removed" and "refining_gb" not in d
    assert abs(d["peak_gb"] - (d["references_gb"] + d["maps_gb"] + d["runs_whole_gb"])) <= 2.0   # + the margin
    # what `estimate` prints of it (the same figures, study.engine.disk.describe)
    from study.engine.disk import describe
    text = "\n".join(describe(d))
    assert "disk peaks hold over every round" in text
    assert "disk at its peak:" in text and f"{d['peak_gb']:.1f} GB" in text
    # its runs kept whole while they refine within its 15 GB budget, the rest pruned once judged
    # and remade if refined: the budget (with the disk's margin) is its peak
    assert d["runs_while_refining"] == "whole" and d["budget_gb"] == 15
    assert d["least_gb"] <= d["planned_gb"] < d["peak_gb"] and d["planned_gb"] <= 15 + 2
    assert f"disk planned: {d['planned_gb']:.1f} GB (runs whole while their tests refine" in text
    assert "within the profile's disk_budget_gb of 15 GB" in text
