"""The sharpen strength sweep (a factor of the findings, study.reporting.sharpen_sweep): a numeric strength is the named kernel at its w,
the landing strength by hand, and a tiny study whose sweep agrees with its own static columns."""
import json

import numpy as np
import pytest

import taa_impl
from study.config.profile import sharpen_sweep_configs, sharpen_sweep_point
from study.reporting.sharpen_sweep import landings

F = np.float32


def _frames(n=5, seed=0):
    rng = np.random.default_rng(seed)
    h, w = 9, 11
    out = []
    for _ in range(n):
        c = rng.uniform(0.0, 2.0, (h, w, 3)).astype(F)
        d = np.full((h, w), 10.0, F)
        out.append(dict(color=c, albedo=np.full((h, w, 3), 0.5, F), depth=d, prev_depth=d.copy(),
                        object_id=np.ones((h, w), np.int32), motion=np.zeros((h, w, 2), F)))
    return out


@pytest.mark.parametrize("name", ["taa_baseline", "taa_improved"])
def test_a_strength_is_the_named_kernel_at_its_w_bit_for_bit(name):
    frames = _frames()
    outs = {}
    for s in ("xu", 1.0, 1, "normalised", 0.25, "none", 0, 0.5):
        t = taa_impl.make(name, sharpen=s)
        outs[s] = [t.process(fr, jitter=(0.1 * i % 0.5, -0.2), far=100.0) for i, fr in enumerate(frames)]
    for a, b in (("xu", 1.0), ("xu", 1), ("normalised", 0.25), ("none", 0)):
        for x, y in zip(outs[a], outs[b]):
            np.testing.assert_array_equal(x, y)
    # and a strength between is neither end
    assert not np.array_equal(outs[0.5][-1], outs["xu"][-1]) and not np.array_equal(outs[0.5][-1], outs[0.25][-1])
    assert taa_impl.make(name, sharpen=1).params == taa_impl.make(name, sharpen=1.0).params


@pytest.mark.parametrize("bad", [-0.1, 4.5, float("nan"), "sharp", True, [1]])
def test_a_bad_strength_is_refused_naming_it(bad):
    with pytest.raises(ValueError, match="sharpen"):
        taa_impl.make("taa_baseline", sharpen=bad)


def test_landing_strengths_by_hand():
    pts = [(0.0, 40.0), (0.25, 36.0), (1.0, 24.0)]
    assert landings(pts, 38.0) == [pytest.approx(0.125)]
    assert landings(pts, 30.0) == [pytest.approx(0.625)]
    assert landings(pts, 36.0) == [0.25]
    assert landings(pts, 41.0) == [] and landings(pts, 20.0) == []
    assert landings([(0.0, 30.0), (0.5, 34.0), (1.0, 30.0)], 32.0) == [pytest.approx(0.25), pytest.approx(0.75)]


def test_sweep_labels_round_trip():
    cs = sharpen_sweep_configs([0, 0.0625, 1])
    assert [c.label for c in cs][:3] == ["Uncharted, sharpen w=0", "Uncharted, sharpen w=0.0625", "Uncharted, sharpen w=1"]
    assert [sharpen_sweep_point(c.label) for c in cs] == [("Uncharted", 0.0), ("Uncharted", 0.0625), ("Uncharted", 1.0),
                                                          ("Improved", 0.0), ("Improved", 0.0625), ("Improved", 1.0)]
    assert sharpen_sweep_point("Uncharted") is None and sharpen_sweep_point("Mine, sharpen w=1") is None


STUDY = """
name = "sweep"
scenes = ["pipe", "hairball_lit"]
resolution = [40, 24]
agreement = false
sharpen_sweep = [0, 0.25, 1]
sharpen_sweep_scenes = ["hairball_lit"]
out = "{out}"
[[techniques]]
spec = "No AA=noaa"
[[techniques]]
spec = "FXAA=fxaa"
[[techniques]]
spec = "Uncharted=taa_baseline"
[[techniques]]
spec = "Improved=taa_improved"
[protocols.static]
history = 8
checkpoints = [4, 8]
thesis_history = 4
[[protocols.ghosting]]
name = "ghosting"
frames = 1
[precision]
rule = "per_pixel"
[reference]
se_bound_lsb = 2.0          # what is checked holds at any reference precision: each sweep point and its
target_noise_db = 0.0       # static column are one output judged against one reference (0.5 LSB: 3/4 of the time)
[video]
metric = "none"
"""


@pytest.mark.long(seconds=15)
def test_a_study_sweeps_the_sharpen_and_its_own_kernels_equal_the_static_columns(tmp_path, monkeypatch, no_plots):
    from study_fixtures import run_cli
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "out"
    (tmp_path / "s.toml").write_text(STUDY.format(out=out))
    run_cli(["run", tmp_path / "s.toml"])
    figs = json.loads((out / "tables" / "figures.json").read_text())
    static = next(t for t in figs["tests"] if t["scene"] == "hairball_lit" and t["protocol"] == "static")
    csv = (out / "tables" / "sharpen_sweep.csv").read_text().splitlines()
    assert csv[0].startswith("scene,TAA,thesis,w=0,w=0.25,w=1,")
    rows = {r.split(",")[1]: r.split(",") for r in csv[1:]}
    assert set(rows) == {"Uncharted", "Improved"} and all(r[0] == "hairball_lit" for r in rows.values())
    # each TAA's own kernel in the sweep is its static column at the thesis's history: the same
    # output judged against the same reference (Uncharted: Xu's, w = 1; Improved: normalised, 0.25)
    rec = json.loads((out / "tables" / "findings.json").read_text())
    f = next(x for x in rec["factors"] if x["id"] == "sharpen_strength")
    curve = {c["taa"]: {w: p for w, p, _ in c["points"]} for c in f["cases"]}
    for role, w in (("Uncharted", 1.0), ("Improved", 0.25)):
        psnr = static["techniques"][role]["frames"]["4"]["figures"]["psnr"]
        assert curve[role][w] == psnr, role
    assert curve["Uncharted"][0.0] != curve["Uncharted"][1.0]
    assert curve["Uncharted"][0.25] != curve["Improved"][0.25]       # two TAAs, not one twice
    # the thesis's hairball_lit figures (16.535 / 24.579) lie on no curve at 40x24 or somewhere on it;
    # whichever, the record says which
    for c in f["cases"]:
        lo, hi = c["range"]
        assert bool(c["landing"]) == (lo <= c["thesis"] <= hi)
    assert {x["id"] for x in rec["factors"]} == {"sharpen_strength", "rebuilt_scenes"}
    rebuilt = next(x for x in rec["factors"] if x["id"] == "rebuilt_scenes")
    assert {c["scene"] for c in rebuilt["cases"]} == {"pipe", "hairball_lit"}
    for c in rebuilt["cases"]:
        assert c["scene_gap"] == pytest.approx((c["gaps"]["No AA"] + c["gaps"]["FXAA"]) / 2)
        assert c["excess"]["Improved"] == pytest.approx(c["gaps"]["Improved"] - c["scene_gap"])
    # the sweep's columns are in no other table
    assert "sharpen w=" not in (out / "tables" / "static_hairball_lit.csv").read_text()
    assert any("The sharpen's strength" in line for line in (out / "study.md").read_text().splitlines())
