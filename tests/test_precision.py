"""Each figure's reference uncertainty (study.metrics.uncertainty), the references' halves it is
estimated from (references.render), and precision set by the figures (study.engine.precision)."""
import json
import math
import shutil

import numpy as np
import pytest

from study.config.precision import Precision
from study.metrics import uncertainty as U


def _mse(t, r):
    return {"mse": float(np.mean((t - r) ** 2)), "psnr": 0.0}


def test_jackknife_removes_the_mse_bias_of_a_noisy_reference():
    """MSE against a reference with noise variance v is biased by mean(v); the jackknife over two
    independent halves removes it, and |f(A) - f(B)| is about 2 sd of what is left."""
    rng = np.random.default_rng(1)
    n = 400_000
    mu = rng.uniform(0, 255, n)
    t = mu + rng.normal(0, 3.0, n)                         # a technique: MSE 9 against the truth
    sd_half = rng.uniform(0.5, 4.0, n) * math.sqrt(2)      # each half: twice the full's variance
    a, b = mu + rng.normal(0, 1, n) * sd_half, mu + rng.normal(0, 1, n) * sd_half
    full = (a + b) / 2
    truth = float(np.mean((t - mu) ** 2))
    f = _mse(t, full)
    bias = float(np.mean(sd_half ** 2 / 2))
    assert f["mse"] - truth == pytest.approx(bias, rel=0.05)        # the plain figure is biased
    c, u = U.jackknife(f, _mse(t, a), _mse(t, b))
    sd = 2 * math.sqrt(np.sum((t - mu) ** 2 * sd_half ** 2 / 2)) / n   # sd of the -2 mean(d e) term
    assert abs(c["mse"] - truth) < 4 * sd < 0.05 * bias
    assert 0.02 * sd < u["mse"] < 8 * sd
    assert c["psnr"] == pytest.approx(10 * math.log10(255 ** 2 / c["mse"]))
    assert c["rmsd"] == pytest.approx(math.sqrt(c["mse"]))
    assert u["psnr"] == pytest.approx(10 / math.log(10) * u["mse"] / c["mse"])


def test_jackknife_edge_cases():
    c, u = U.jackknife({"mse": 0.0, "psnr": math.inf, "ssim": 1.0, "flip_hdr": None},
                       {"mse": 0.5, "psnr": 51.0, "ssim": 0.99, "flip_hdr": None},
                       {"mse": 0.1, "psnr": 58.1, "ssim": 0.999, "flip_hdr": None})
    assert c["mse"] == 0.0 and c["psnr"] == math.inf and u["psnr"] == 0.0    # MSE never below 0
    assert c["flip_hdr"] is None and u["flip_hdr"] is None                  # undefined stays undefined
    assert c["ssim"] == pytest.approx(2 - (0.99 + 0.999) / 2) and u["ssim"] == pytest.approx(0.009)


def test_pooled_tolerance_and_digits():
    assert U.pooled([0.3, 0.4]) == pytest.approx(0.25)
    assert U.pooled([0.1, None]) is None
    tol = Precision().tolerances
    assert U.tolerance("psnr", 40.0, tol) == 0.01
    assert U.tolerance("mse", 10.0, tol) == pytest.approx(0.023)
    assert U.tolerance("relmse_hdr", 1e-3, tol) == pytest.approx(1e-5)
    assert U.over_tolerance({"psnr": 40.0, "ssim": 0.99}, {"psnr": 0.02, "ssim": 5e-5}, tol) == {"psnr": 2.0}
    assert U.decimals("psnr", 0.004, 3) == 2 and U.decimals("psnr", 0.04, 3) == 1
    assert U.decimals("mse", 7.0, 3) == 0 and U.decimals("psnr", None, 3) == 3
    from study.reporting.tables import fmt
    assert fmt("psnr", 42.1234, 0.004) == "42.12" and fmt("psnr", 42.1234) == "42.123"
    assert fmt("relmse_hdr", 1.23456e-4, 2e-6) == "1.23e-04"


def test_precision_levels_and_settings():
    p = Precision(start_bound_lsb=2.0, finest_bound_lsb=0.125)
    assert p.levels() == 4 and p.bound(3) == 0.25
    base = {"se_bound_lsb": 0.5, "target_noise_db": 60.0}
    assert p.settings(base, 2) == {"se_bound_lsb": 0.5, "target_noise_db": 0.0, "held_out": True}
    assert Precision(rule="per_pixel").settings(base, 3) == base


@pytest.mark.parametrize("held_out", [False, True])
def test_reference_halves_are_independent_halves_of_its_samples(held_out):
    from references.render import render_reference
    from study.engine.tasks import load_scene
    ref = render_reference(load_scene("pipe"), 0, 64, 36, se_bound_lsb=1.0, target_noise_db=0, held_out=held_out)
    assert ref.held_out == held_out
    a, b = ref.halves()
    assert np.abs((a + b) / 2 - ref.image).max() < 1e-6
    noisy = ref.stderr > 1e-6
    z = ref.half_delta[noisy] / ref.stderr[noisy]
    # (A - B) / 2 has the mean's variance; the reported SE is conservative (it includes the floor)
    assert 0.1 < float(np.mean(z ** 2)) < 1.2
    assert np.all(ref.half_delta[~noisy] == 0)


STUDY = """
name = "eq_{rule}"
scenes = ["pipe", "text_wall", "sphere_ghosting"]
resolution = [80, 45]
ghosting_skip = ["accumulation"]
agreement = false
out = "{out}"
[[techniques]]
spec = "No AA=noaa"
[[techniques]]
spec = "Improved=taa_improved"
[[techniques]]
label = "SSAA 4x"
technique = "accumulation"
params = {{ samples = 4 }}
[protocols.static]
history = 8
checkpoints = [8]
thesis_history = 8
[[protocols.ghosting]]
name = "ghosting"
frames = 2
warmup = 0
[video]
metric = "none"
[precision]
rule = "{rule}"
psnr_db = 0.05
ssim = 5e-4
flip = 5e-4
relative = 0.0115
relmse = 0.05
"""


def _figures(tmp_path, rule):
    from study_fixtures import run_cli
    out = tmp_path / rule
    path = tmp_path / f"{rule}.toml"
    path.write_text(STUDY.format(rule=rule, out=out))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
        run_cli(["run", path])
    return json.loads((out / "tables" / "figures.json").read_text())


@pytest.mark.long(seconds=90)
def test_figures_rule_matches_per_pixel_references_on_three_scenes(tmp_path, no_plots):
    """At the figures' tolerances every figure lies within its tolerance (plus the 0.5-LSB
    figure's own uncertainty) of the figure judged against 0.5-LSB references, no ranking
    changes, and each test's references end at the bound its figures asked for."""
    new, old = _figures(tmp_path, "figures"), _figures(tmp_path, "per_pixel")
    tol = new["tolerances"]
    assert set(new["precision"]) == {"pipe", "text_wall", "sphere_ghosting"}
    assert set(new["precision"]["sphere_ghosting"]) == {"static", "ghosting"}
    tests = [p for per in new["precision"].values() for p in per.values()]
    assert all(not p["over"] for p in tests)
    assert all(p["rounds"][0] == 8.0 and len(p["rounds"]) >= 2 for p in tests)    # probed, then checked finer
    # each test ends at the last bound it tried, every round finer than the one before; whether
    # any ends coarser than 0.5 LSB depends on the references' noise at this size (at 80x45 the
    # SSIM's tolerance asks for 0.25 LSB on every test but pipe's)
    assert all(p["bound_lsb"] == p["rounds"][-1] and all(x > y for x, y in zip(p["rounds"], p["rounds"][1:]))
               for p in tests), new["precision"]
    checked = 0
    for tn, to in zip(new["tests"], old["tests"]):
        assert (tn["scene"], tn["protocol"]) == (to["scene"], to["protocol"])
        for label, tech in tn["techniques"].items():
            for f, fr in tech["frames"].items():
                ofr = to["techniques"][label]["frames"][f]
                for m, v in fr["figures"].items():
                    t = U.tolerance(m, v, tol)
                    if v is None or t is None or not math.isfinite(v):
                        continue
                    assert abs(v - ofr["figures"][m]) <= t + ofr["uncertainty"][m] + 1e-12, (tn["scene"], label, m)
                    checked += 1
        for m in ("psnr", "ssim", "flip_ldr"):
            def order(t):
                vals = {l: next(iter(x["frames"].values()))["figures"][m] for l, x in t["techniques"].items()}
                return sorted(vals, key=vals.get)
            assert order(tn) == order(to), (tn["scene"], m)
    assert checked >= 3 * 3 * 6


def test_display_transform_does_not_follow_the_reference_noise():
    """Two references of one frame at different precisions give one display transform (a
    display-space technique's input depends on it: FXAA moved 0.036 dB on text_wall when it did)."""
    from display import DisplayTransform
    rng = np.random.default_rng(3)
    img = rng.uniform(0.05, 2.0, (90, 160, 3))
    img[0, 0] = 1.234567                       # the brightest pixel sets the white point
    noisy = img * (1 + rng.normal(0, 1e-5, img.shape))
    noisy[0, 0] = img[0, 0]
    a, b = DisplayTransform.from_reference(img), DisplayTransform.from_reference(noisy)
    assert (a.log_average, a.white) == (b.log_average, b.white)
    assert f"{a.log_average:.3g}" == repr(a.log_average)


def test_drift_counts_only_the_change_the_halves_do_not_explain():
    from study.engine.precision import drift
    tol = Precision().tolerances
    now = {("static", "A", 8, "psnr"): (30.00, 0.002), ("static", "A", 8, "ssim"): (0.9000, 1e-5)}
    before = {("static", "A", 8, "psnr"): (30.05, 0.004), ("static", "A", 8, "ssim"): (0.90005, 4e-5)}
    change, over = drift(now, before, tol)
    assert change[("static", "A", 8, "psnr")] == pytest.approx(0.05 - 0.006)
    assert change[("static", "A", 8, "ssim")] == pytest.approx(0, abs=1e-12)   # within the two noises
    assert over == [("static", "A", 8, "psnr", pytest.approx(0.044), 0.01)]


def test_drift_scaled_to_the_finer_bound_and_the_level_the_figures_ask_for():
    """A change from 8 to 2 LSB that shrinks in proportion to the bound leaves b / (b0 - b) = 1/3 of
    it at 2 LSB; a figure whose uncertainty is 10x its tolerance asks for ceil(log2(10 x 1.5)) = 4
    levels more (u falls with the bound), one within it for the one level a drift needs."""
    from study.engine.precision import MARGIN, decide, drift, levels_asked
    tol = Precision().tolerances
    change, over = drift({("s", "A", 8, "psnr"): (30.00, 0.0)}, {("s", "A", 8, "psnr"): (30.06, 0.0)}, tol, 2 / (8 - 2))
    assert change[("s", "A", 8, "psnr")] == pytest.approx(0.02) and len(over) == 1
    assert MARGIN == 1.5
    assert levels_asked(0.1, 0.01) == 4 and levels_asked(1e-5, 1e-4) == -2 and levels_asked(0.3, 0.0) == 0
    A = ("s", "static")
    figs = {("static", "A", 8, "psnr"): (30.0, 0.1), ("static", "A", 8, "ssim"): (0.9, 1e-5)}
    assert decide({A: figs}, {}, {}, Precision(), {}, {}).finer == {A: {None: 4}}
    assert decide({A: figs}, {}, {A: 2}, Precision(finest_bound_lsb=0.25), {}, {}).finer == {A: {None: 5}}   # at most the finest
    ssim = {("static", "A", 8, "ssim"): (0.9, 2e-4)}         # over, asks 2: at least one level finer than 1
    assert decide({A: ssim}, {}, {A: 1}, Precision(), {}, {}).finer == {A: {None: 3}}
    zero = {("static", "A", 8, "mse"): (0.0, 0.3)}            # over a tolerance of 0, no scale: one level finer
    assert decide({A: zero}, {}, {}, Precision(), {}, {}).finer == {A: {None: 1}}


def test_a_ghosting_test_refines_the_instants_its_figures_are_over_at_and_the_temporal_rms_all():
    """Frames 0-2 of a ghosting test are judged against the references of scene times 10-12. Frame
    2's FLIP over its tolerance (4e-4 > 1e-4: asks ceil(log2(6)) = 3 levels) refines time 12 alone;
    a temporal RMS over (a figure of every frame: asks ceil(log2(0.05 x 1.5 / 0.023)) = 2) refines
    every instant from the coarsest. In the round after, a figure's drift is its change over its own
    instants' bounds (8 -> 1 LSB: x 1/7), and frames whose references did not change keep theirs."""
    from study.engine.precision import decide, level_at
    from study.engine.rounds import InstantKey
    G = ("s", "ghosting")
    inst = {G: {("X", 0): 10, ("X", 1): 11, ("X", 2): 12}}
    f0, f2, tr = ("ghosting", "X", 0, "flip_hdr"), ("ghosting", "X", 2, "flip_hdr"), ("ghosting", "X", None, "temporal")
    p = Precision()
    probe = {f0: (0.1, 0.5e-4), f2: (0.1, 4e-4), tr: (10.0, 0.001)}
    levels, before, over, drifts = {}, {}, {}, {}
    finer, judged, over, drifts, before = decide({G: probe}, before, levels, p, over, drifts, inst)
    assert judged == {G} and finer == {G: {12: 3}} and [x[2] for x in over[G]] == [2]
    levels.update({InstantKey(*G, t): n for t, n in finer[G].items()})
    assert [level_at(levels, G, t) for t in (10, 11, 12)] == [0, 0, 3]
    # frame 2 moved 0.0003 at 1 LSB (beyond the 4.5e-4 of both halves? no: within): no drift;
    # the temporal RMS moved 0.009 - 0.002 of noise = 0.007, x 1 / (8 - 1) = 0.001: within 0.023
    finer, judged, over, drifts, before = decide({G: {f0: (0.1, 0.5e-4), f2: (0.1003, 0.4e-4), tr: (10.009, 0.001)}},
                                                 before, levels, p, over, drifts, inst)
    assert judged == {G} and finer == {} and over[G] == []
    assert drifts[G][f2] == 0.0 and drifts[G][tr] == pytest.approx(0.007 / 7) and f0 not in drifts[G]
    # nothing changed: not judged again
    assert decide({G: {f0: (0.1, 0.5e-4)}}, before, levels, p, over, drifts, inst)[:2] == ({}, set())
    finer = decide({G: {**probe, tr: (10.0, 0.05)}}, {}, {}, p, {}, {}, inst).finer
    assert finer == {G: {10: 2, 11: 2, 12: 3}}
    from study.engine.precision import bounds_text     # how the log and the table print them
    assert bounds_text({0.5: 2, 1.0: 22}) == "1 (22 instants), 0.5 (2)"
    assert bounds_text({2.0: 1, 1.0: 3}) == "2 (1 instant), 1 (3)" and bounds_text({4.0: 5}) == "4"


def test_a_ghosting_test_s_means_over_frames_are_figures_with_pooled_uncertainty_of_every_instant():
    """figures_of(means=True) adds each column's mean over the frames, its uncertainty
    sqrt(sum u^2) / n (the frames' references are independent renders), where every frame has a
    finite figure; the mean's tolerance is its metric's, and a mean over it refines every instant."""
    from types import SimpleNamespace
    from study.engine.precision import decide, figures_of
    from study.metrics.uncertainty import tolerance
    res = SimpleNamespace(per_frame={"X": {0: {"mse": 2.0, "psnr": 30.0}, 1: {"mse": 4.0, "psnr": math.inf}}},
                          uncertainty={"X": {0: {"mse": 0.3, "psnr": 0.01}, 1: {"mse": 0.4, "psnr": 0.02}}},
                          temporal={"X": 1.5}, temporal_u={"X": 0.01})
    plain = figures_of(res)
    assert set(plain) == {("X", 0, "mse"), ("X", 0, "psnr"), ("X", 1, "mse"), ("X", None, "temporal")}
    got = figures_of(res, means=True)
    assert set(got) - set(plain) == {("X", None, "mse_mean")}          # no PSNR mean: frame 1's is infinite
    assert got[("X", None, "mse_mean")] == pytest.approx((3.0, 0.25))  # sqrt(0.09 + 0.16) / 2
    tol = Precision().tolerances
    assert tolerance("mse_mean", 3.0, tol) == tolerance("mse", 3.0, tol) == pytest.approx(0.0023 * 3.0)
    G = ("s", "ghosting")
    inst = {G: {("X", 0): 10, ("X", 1): 11}}
    # 0.25 x 1.5 / (0.0023 x 3) asks ceil(log2(54.3)) = 6 levels, capped at the finest (5), at both instants
    finer = decide({G: {("ghosting", "X", None, "mse_mean"): (3.0, 0.25)}}, {}, {}, Precision(), {}, {}, inst).finer
    assert finer == {G: {10: Precision().levels(), 11: Precision().levels()}}


def test_snr_is_derived_from_the_corrected_mse_as_psnr_is():
    """SNR = 10 log10(P / MSE): corrected through the MSE, it keeps its offset to PSNR (the
    reference's power) and PSNR's uncertainty; jackknifed in dB on its own it would not."""
    def figs(mse, power):
        return {"mse": mse, "psnr": 10 * math.log10(255 ** 2 / mse), "snr": 10 * math.log10(power / mse)}
    full, a, b = figs(0.30, 9000.0), figs(0.42, 9001.0), figs(0.38, 8999.0)
    c, u = U.jackknife(full, a, b)
    assert c["mse"] == pytest.approx(2 * 0.30 - 0.40)
    assert c["snr"] - c["psnr"] == pytest.approx(full["snr"] - full["psnr"])
    assert c["snr"] == pytest.approx(10 * math.log10(9000.0 / 0.20))
    assert u["snr"] == u["psnr"] == pytest.approx(10 / math.log(10) * 0.04 / 0.20)
    assert 2 * full["snr"] - (a["snr"] + b["snr"]) / 2 != pytest.approx(c["snr"], abs=0.1)   # the dB jackknife differs


def test_one_display_transform_per_frame_at_every_precision(tmp_path):
    """A display-space technique's run and every frame's transform come from the frame's probe
    reference: references of a test at another bound change its metrics' keys, not FXAA's run."""
    from study.engine.plan import Planner
    from study.engine.tasks import Context, display_of, load_scene
    from study.config.protocols import Protocol
    from study.config.techniques import TechniqueConfig
    from references import ReferenceCache
    from display import DisplayTransform
    scene = load_scene("pipe")
    ctx = Context(str(tmp_path), 1)
    p = Precision()
    base = {"se_bound_lsb": 0.5, "target_noise_db": 60.0}
    disp = p.display_settings(base)
    assert disp == {"se_bound_lsb": 8.0, "target_noise_db": 0.0, "held_out": True}
    proto = Protocol("static", "static", history=4, checkpoints=(4,))
    fx = [TechniqueConfig.parse("FXAA=fxaa")]
    keys = []
    for level in (0, 3):
        pl = Planner(ctx, base, None, {("pipe", proto.name): p.settings(base, level)}, disp)
        t = pl.add_test("pipe", scene, proto, fx, 32, 18)
        keys.append((t.run_keys["FXAA"], t.metrics_keys["FXAA"]))
    assert keys[0][0] == keys[1][0] and keys[0][1] != keys[1][1]
    cache = ReferenceCache(tmp_path)
    got = display_of(cache, scene, 0, 32, 18, disp)
    assert got == DisplayTransform.from_reference(cache.get(scene, 0, 32, 18, **disp)[0].image)


def test_decide_refines_each_test_on_its_own_and_leaves_a_settled_one_alone():
    """Round 1 probes both tests at 8 LSB; A settles at the level it asks for, B's drift from the
    probe sends it on; in round 3 only B's bound changed, so A is neither judged again nor given a
    drift against itself (b0 = b)."""
    from study.engine.precision import decide
    p = Precision()                                   # 8 LSB probe, finest 0.125: 6 levels
    A, B = ("s", "static"), ("s", "ghosting")
    levels, before, over, drifts = {}, {}, {}, {}
    f = ("static", "X", 8, "psnr")
    finer, judged, over, drifts, before = decide({A: {f: (40.0, 0.03)}, B: {f: (30.0, 0.012)}}, before, levels, p,
                                                 over, drifts)
    # u falls with the bound: A asks ceil(log2(0.03 x 1.5 / 0.01)) = 3 levels (1 LSB), B 1 (4 LSB)
    assert judged == {A, B} and finer == {A: {None: 3}, B: {None: 1}} and over[A] and over[B]
    levels.update({k: n[None] for k, n in finer.items()})
    finer, judged, over, drifts, before = decide({A: {f: (40.004, 0.002)}, B: {f: (30.1, 0.004)}}, before, levels, p,
                                                 over, drifts)
    # A: the change 0.004 is within both noises (0.002 + 0.03): no drift, and u 0.002 <= 0.01
    assert judged == {A, B} and over[A] == [] and drifts[A][f] == 0.0 and A not in finer
    # B: (0.1 - 0.004 - 0.012) x 4 / (8 - 4) = 0.084 left at 4 LSB: over, on to ceil(log2(...))
    assert drifts[B][f] == pytest.approx(0.084) and over[B] and finer == {B: {None: 1 + math.ceil(math.log2(0.088 * 1.5 / 0.01))}}
    levels.update({k: n[None] for k, n in finer.items()})
    finer, judged, over, drifts, before = decide({A: {f: (40.004, 0.002)}, B: {f: (30.11, 0.001)}}, before, levels, p,
                                                 over, drifts)
    assert judged == {B} and over[A] == [] and drifts[A][f] == 0.0


def test_a_test_within_tolerance_at_the_probe_settles_there_unless_confirm_asks_for_a_second_bound():
    from study.engine.precision import decide
    A, f = ("s", "static"), ("static", "X", 8, "psnr")
    for confirm, want in ((False, {}), (True, {A: {None: 1}})):
        finer, judged, over, _, _ = decide({A: {f: (40.0, 0.009)}}, {}, {}, Precision(confirm=confirm), {}, {})
        assert judged == {A} and over[A] == [] and finer == want, confirm
    # over its tolerance at the probe: refined either way
    finer = decide({A: {f: (40.0, 0.011)}}, {}, {}, Precision(), {}, {}).finer
    assert finer == {A: {None: 1}}


@pytest.mark.long(seconds=25)
def test_a_study_of_the_same_tasks_replays_the_precision_decisions(tmp_path, monkeypatch, reference_pool):
    """A no-op study plans its final round alone (its inputs — profile, scenes, columns, code — are
    an earlier study's, whose decisions are recorded under its probe's keys), and states the same
    bounds, drifts and figures as a study that decides afresh. Relabelled columns are other inputs
    but the same probe: probe and final plans, the probe's record replayed; an edited technique's
    probe is a new key, so it decides afresh."""
    from study_fixtures import write_scenes
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    scenes = write_scenes(tmp_path)[:1]
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]
    plans = []
    real_plan = Study.plan

    def counting_plan(self, *a, **k):
        plans.append(k.get("agreement", a[2] if len(a) > 2 else True))
        return real_plan(self, *a, **k)
    monkeypatch.setattr(Study, "plan", counting_plan)

    def study(cs=configs):
        plans.clear()
        s = Study(get_profile("quick"), cache_root=tmp_path / "cache", progress=False)
        res = s.run(scenes, cs, agreement=True)
        figs = {(t.scene, t.test): (t.per_frame, t.uncertainty, t.temporal_u)
                for t in res.statics + [g for gs in res.ghosts.values() for g in gs]}
        return res, figs, len(plans), s.drifts

    reference_pool.seed(tmp_path / "cache")      # the planning is checked here, not the references
    first, figs1, n1, drifts1 = study()
    reference_pool.keep(tmp_path / "cache")
    rounds = {k: p["rounds"] for k, per in first.precision.items() for p in per.values()}
    # probed, then refined, then the agreement against the final references
    assert n1 >= 3 and min(len(r) for r in rounds.values()) >= 2 and plans[-1], (n1, rounds)
    again, figs2, n2, drifts2 = study()
    assert n2 == 1 and again.stats["tasks"] == {} and again.agreements == first.agreements
    assert again.stats["task_seconds"] == {}                # nothing ran, nothing timed
    assert again.precision == first.precision and drifts2 == drifts1 and figs2 == figs1
    # afresh (the record removed): the same decisions, from the rounds themselves
    for p in (tmp_path / "cache" / "precision").rglob("*.json"):
        p.unlink()
    fresh, figs3, n3, drifts3 = study()
    assert n3 == n1 and fresh.precision == first.precision and drifts3 == drifts1 and figs3 == figs1
    relabelled = [configs[0], TechniqueConfig.parse("other=noaa")]    # the same content: the same keys
    assert study(relabelled)[2] == 2
    edited = [TechniqueConfig.parse("taa_baseline:k_min=0.5"), configs[1]]
    assert study(edited)[2] >= 3


@pytest.mark.long(seconds=20)
def test_a_seeded_study_starts_each_test_at_the_bound_an_earlier_study_settled(tmp_path, reference_pool):
    """What `ab` runs: with one technique added, every test starts at the bound the study settled
    it at (no probe round: the settled column's figures there are cached), and is refined only where
    the new column's figures ask for it; unseeded, the same study starts at the probe."""
    from study_fixtures import write_scenes
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    scenes = write_scenes(tmp_path)[:1]
    a, b = (TechniqueConfig.parse(s) for s in ("taa_baseline", "B=taa_baseline:sharpen=none"))
    logs = []

    def study(cs, seeded):
        logs.clear()
        s = Study(get_profile("quick"), cache_root=tmp_path / "cache", progress=False, log=logs.append)
        res = s.run(scenes, cs, agreement=False, seeded=seeded)
        return {(n, p): r["rounds"] for n, per in res.precision.items() for p, r in per.items()}, res
    reference_pool.seed(tmp_path / "cache")
    first, _ = study([a], False)
    reference_pool.keep(tmp_path / "cache")
    assert all(r[0] == 8.0 and len(r) >= 2 for r in first.values()), first    # probed, then refined
    seeded, res = study([a, b], True)
    assert any("start at the bound an earlier study settled" in m for m in logs), logs
    assert {k: r[0] for k, r in seeded.items()} == {k: r[-1] for k, r in first.items()}, (seeded, first)
    assert res.stats["references_rendered"] == 0 or any(len(r) > 1 for r in seeded.values())
    unseeded, _ = study([a, TechniqueConfig.parse("C=taa_baseline:sharpen=xu")], False)
    assert all(r[0] == 8.0 for r in unseeded.values())


@pytest.mark.long(seconds=20)
def test_a_seeded_study_plans_its_agreement_beside_the_new_column_s_runs(tmp_path, monkeypatch, reference_pool):
    """`ab`'s loop: a test seeded at an earlier study's bound plans its agreement (and video) in the
    first round, beside the new column's runs; where no test is refined that round is the last
    (no round of its own for what the final references feed). The same figures as a study that
    waits for a last round."""
    from study_fixtures import write_scenes
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine import runner
    from study.engine.runner import Study
    scenes = write_scenes(tmp_path)[:1]
    a, b = (TechniqueConfig.parse(s) for s in ("noaa", "B=taa_baseline:sharpen=none"))
    rounds, real_plan = [], Study.plan

    def plan(self, *a_, **k):
        out = real_plan(self, *a_, **k)
        rounds.append(sorted(t.kind for t in out[0].tasks.values()))
        return out
    monkeypatch.setattr(Study, "plan", plan)

    def study(cache, cs, seeded):
        rounds.clear()
        res = Study(get_profile("quick"), cache_root=tmp_path / cache, progress=False).run(
            scenes, cs, agreement=seeded is not None, seeded=bool(seeded))
        return res, list(rounds)
    reference_pool.seed(tmp_path / "early")
    study("early", [a], None)
    reference_pool.keep(tmp_path / "early")
    # the same references in both caches (content-keyed cache hits): what differs is the planning
    shutil.copytree(tmp_path / "early" / "references", tmp_path / "late" / "references")
    study("late", [a], None)
    res, planned = study("early", [a, b], True)
    refined = any(len(r["rounds"]) > 1 for per in res.precision.values() for r in per.values())
    assert not refined, res.precision        # noaa's bound holds B's figures here (else a finer round)
    # the probe's plan, then the seeded one: runs, metrics and the agreement together, and no more
    assert len(planned) == 2 and "agreement" in planned[1] and "run" in planned[1], planned
    monkeypatch.setattr(runner, "_seeded_early", lambda *a_: frozenset())
    late, late_planned = study("late", [a, b], True)
    assert len(late_planned) == 3 and "agreement" in late_planned[2] and "agreement" not in late_planned[1]
    strip = lambda ag: {n: {k: v for k, v in x.items() if not k.endswith("_seconds") and k != "sha256"}  # noqa: E731
                        for n, x in ag.items()}
    assert strip(late.agreements) == strip(res.agreements) and late.precision == res.precision


def test_a_seeded_ghosting_test_is_planned_early_only_with_its_scene_s_other_ghosting_protocols():
    from study.engine.runner import _seeded_early
    tests = [("s", "static"), ("s", "ghosting"), ("s", "ghosting_warm"), ("t", "ghosting_warm"), ("u", "static")]
    seeded = {("s", "static"), ("s", "ghosting_warm"), ("t", "ghosting_warm")}
    assert _seeded_early(tests, seeded, {"ghosting", "ghosting_warm"}) == {("s", "static"), ("t", "ghosting_warm")}
    assert _seeded_early(tests, seeded | {("s", "ghosting")}, {"ghosting", "ghosting_warm"}) == seeded | {("s", "ghosting")}


def test_the_ghosting_protocols_share_an_instant_s_reference_at_the_finest_level_either_asks(tmp_path):
    """The cold and the warm ghosting tests judge the same instants: each instant is rendered once,
    at the finer of their levels; the static test's instants (its control columns ask for finer
    bounds every round) and another scene's stay their own."""
    from study.engine.runner import Study
    s = Study("quick", cache_root=tmp_path, progress=False)
    from study.engine.rounds import InstantKey as I, TestKey
    s.levels.update({I("a", "ghosting", 3): 2, I("a", "ghosting_warm", 3): 4, I("a", "ghosting_warm", 5): 1,
                     I("a", "static", 0): 6, I("b", "ghosting", 3): 3, TestKey("a", "ghosting"): 1})
    assert [s.level_of("a", p, 3) for p in ("ghosting", "ghosting_warm")] == [4, 4]
    assert s.level_of("a", "ghosting", 5) == 1 and s.level_of("a", "ghosting", 7) == 1   # the test's own
    assert s.level_of("a", "ghosting_warm", 7) == 0 and s.level_of("a", "ghosting", 0) == 1
    assert s.level_of("a", "static", 3) == 0 and s.level_of("b", "ghosting_warm", 3) == 3
    assert s.settings_for("a", "ghosting", 3) == s.settings_for("a", "ghosting_warm", 3)
    assert s.bound_of("a", "ghosting", 3) == 8.0 / 2 ** 4


@pytest.mark.long(seconds=20)
def test_a_settled_test_s_agreement_runs_while_other_tests_still_refine(tmp_path, monkeypatch, reference_pool):
    """The agreement (and the video metric) is judged against a test's final references: planned in
    the round after the test settles rather than in a last round of its own, so it fills the rounds
    the other tests still refine in. A ghosting test is settled only once no ghosting protocol of
    its scene is refined (they share the instants' references). The same figures as waiting for the
    last round."""
    from study_fixtures import quick_every_frame, write_scenes
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    scenes = write_scenes(tmp_path)
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]
    finals, real_plan = [], Study.plan

    def study(cache, wait=False):
        finals.clear()

        def plan(self, *a, **k):
            if wait and isinstance(k.get("final"), frozenset):
                k["final"] = frozenset()           # the former rule: nothing before the last round
            finals.append(k.get("final"))
            out = real_plan(self, *a, **k)
            finals[-1] = (finals[-1], sorted(t.kind for t in out[0].tasks.values()))
            return out
        monkeypatch.setattr(Study, "plan", plan)
        s = Study(quick_every_frame(), cache_root=tmp_path / cache, progress=False)
        res = s.run(scenes, configs, agreement=True)
        return res, list(finals)
    reference_pool.seed(tmp_path / "early")
    res, rounds = study("early")
    reference_pool.keep(tmp_path / "early")
    # tiny_moving's warm ghosting test refines one instant in the third round; both static tests settled
    refining = [(f, kinds) for f, kinds in rounds if isinstance(f, frozenset) and "metrics" in kinds and f]
    assert refining, rounds
    f, kinds = refining[-1]
    assert {("tiny_moving", "static"), ("tiny_still", "static")} <= f and kinds.count("agreement") == 2
    assert not {("tiny_moving", "ghosting"), ("tiny_moving", "ghosting_warm")} & f      # its cold twin waits too
    assert rounds[-1][0] is True and "agreement" not in rounds[-1][1]     # the last round finds them done
    # the second study starts with the first one's references (content-keyed cache hits): what it
    # checks is when the agreement is planned, and rendering them again was half of this test's time
    shutil.copytree(tmp_path / "early" / "references", tmp_path / "late" / "references")
    late, late_rounds = study("late", wait=True)
    def figures(agreements):          # its timings, their seal and whether its reference was a cache hit
        return {n: {k: v for k, v in a.items() if not k.endswith("_seconds") and k not in ("sha256", "reference_cached")}
                for n, a in agreements.items()}
    assert "agreement" in late_rounds[-1][1] and figures(late.agreements) == figures(res.agreements)
    assert sorted(late.agreements) == ["tiny_moving", "tiny_still"]
    assert late.precision == res.precision


@pytest.mark.long(seconds=15)
def test_a_ghosting_test_is_judged_and_refined_on_the_figures_it_prints(tmp_path, monkeypatch, reference_pool):
    """A ghosting table prints MSE, PSNR, SSIM and FLIP LDR per frame and the temporal RMS: those
    alone set its references' bounds (FLIP HDR, printed by no ghosting table, had set
    hairball_rotating_lit's), and its frames are not judged in HDR; a static test is bound by,
    and prints, every figure."""
    from study_fixtures import write_scenes
    from study.config.profile import get_profile
    from study.config.protocols import GHOSTING_FIGURES
    from study.config.techniques import TechniqueConfig
    from study.engine import runner as RN
    scenes = write_scenes(tmp_path)
    seen, real = [], RN.decide
    monkeypatch.setattr(RN, "decide", lambda now, *a, **k: seen.append(now) or real(now, *a, **k))
    reference_pool.seed(tmp_path / "c")
    s = RN.Study(get_profile("quick"), cache_root=tmp_path / "c", progress=False)
    res = s.run(scenes, [TechniqueConfig.parse(x) for x in ("taa_baseline", "noaa")], agreement=False)
    bound = {kind: {k[-1] for now in seen for test, figs in now.items() for k in figs
                    if (test[1] == "static") == (kind == "static")} for kind in ("static", "ghosting")}
    # the quick profile bounds a ghosting test by each column's means over its frames and its
    # temporal RMS (each frame's figures are exempt there)
    assert bound["ghosting"] == {m + "_mean" for m in GHOSTING_FIGURES} | {"temporal"}, bound
    assert {"flip_hdr", "relmse_hdr", "ssim_volume", "snr", "ssim", "flip_ldr"} <= bound["static"]
    ghosts = [g for gs in res.ghosts.values() for g in gs]
    assert ghosts and res.statics
    for g in ghosts:
        for per in g.per_frame.values():
            assert all(v["flip_hdr"] is None and v["relmse_hdr"] is None and v["flip_ldr"] > 0 for v in per.values())
    for r in res.statics:
        assert all(v["flip_hdr"] > 0 for per in r.per_frame.values() for v in per.values())
