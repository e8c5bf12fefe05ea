"""The precision loop's judge (study.engine.runner.Study.judge_round) leaves out what a study exempts:
a whole column (`[precision] exempt`) or some figures of a column on some tests and scenes
(`[precision]` exemption tables, study.config.precision.Exemption)."""
from dataclasses import replace
from types import SimpleNamespace

from study.config.precision import Exemption
from study.engine import runner as R
from study.engine import rounds


def test_the_round_s_bounding_figures_leave_out_exempt_columns_and_figures(tmp_path, monkeypatch):
    s = R.Study("quick", cache_root=tmp_path, progress=False, log=lambda m: None)
    s.precision = replace(s.precision, exempt=("Accumulation 128",),
                          exemptions=(Exemption("FXAA", ("temporal",), ("ghosting",)),
                                      Exemption(None, ("mse",), (), ("texture_crawl",))))
    figs = {(c, 3, m): (1.0, 0.1) for c in ("FXAA", "Uncharted", "Accumulation 128") for m in ("mse", "psnr")}
    figs.update({(c, None, "temporal"): (2.0, 0.1) for c in ("FXAA", "Uncharted")})
    monkeypatch.setattr(R, "figures_of", lambda res, means=False: figs)
    monkeypatch.setattr(R.Study, "_result", lambda self, t, results, memo: None)
    proto = lambda name: SimpleNamespace(name=name, figures=None, kind="static")   # noqa: E731
    tests = [SimpleNamespace(scene=sc, spec=sc, protocol=proto(p)) for sc, p in
             (("pipe", "ghosting"), ("pipe", "static"), ("texture_crawl", "ghosting"))]
    now = s.judge_round(SimpleNamespace(judged=tests), rounds.Progress(rounds=((None, {}),)))
    got = {k: {(f.label, f.metric) for f in v} for k, v in now.items()}
    every = {(c, m) for c in ("FXAA", "Uncharted") for m in ("mse", "psnr")} | {("Uncharted", "temporal")}
    assert got[rounds.TestKey("pipe", "ghosting")] == every
    assert got[rounds.TestKey("pipe", "static")] == every | {("FXAA", "temporal")}
    assert got[rounds.TestKey("texture_crawl", "ghosting")] == {f for f in every if f[1] != "mse"}
