"""Precision set by the figures: each test's references refined until the reference's share of
every figure's uncertainty is within its tolerance.

A reference's noise matters only through the figures it is judged into, and those figures'
uncertainty is measured, not assumed, in two parts:
  - the noise the two halves of a reference see (study.metrics.uncertainty): random, and the
    bias that scales with the noise's variance, which the jackknife removes;
  - what both halves share, or they understate (`drift`): a sliver every sample of a pixel
    missed, a residual the jackknife leaves where 8-bit rounding makes a figure's dependence on
    the noise non-linear, and, while references were the mean of the samples that decided their
    counts, the stopping rule's bias: on hairball_lit (160x90) the jackknifed MSE of a blurred
    image was 1.2 % high at 8 LSB, 0.07 % at 2 (scripts/reference_bias.py), which drove most
    1600x900 tests to 0.125 LSB. The figures' rule's references are now held out
    (references.estimates: unbiased): the same figure is 220.76 +- 0.49 at 8 LSB against 220.87.
    What is left shrinks with the bound (taken in proportion), so the change of a figure from a
    coarser bound b0 to the bound b estimates what is left of it at b: change x b / (b0 - b).
Only the figures a test prints bound it (`printed`: a ghosting test's MSE, PSNR, SSIM, FLIP LDR per
frame and its temporal RMS; FLIP HDR, which no ghosting table printed, had set hairball_rotating_lit's
bounds). Each test (a scene under one protocol: its static test, each ghosting protocol) has its own bound,
since their figures need different precisions: a near-converged SSAA 16x on pipe (MSE 0.2) needs
~0.25 LSB, a ghosting TAA (MSE ~10^2) far less; and within a test each instant (a ghosting
sequence's frames) has its own: a frame's figures refine that frame's reference, the temporal RMS
(a figure of every frame) the sequence's coarsest ones.
  1. A probe: every reference of the test at `start_bound_lsb` (8 LSB by default, a few times the
     pilot's samples).
  2. A test whose every figure is within its tolerance at the probe is settled there (`confirm`:
     rendered once more at the next bound, to measure the drift as well). Otherwise the bound the
     figures need, predicted from the probe: a figure's halves' uncertainty falls in proportion to
     the bound, so each asks for b tol / (u x MARGIN); the test's references are rendered again at
     the largest power-of-two fraction of the start below what every figure asks, at least one
     level finer.
  3. Checked there: every figure's halves' uncertainty plus its drift from the bound before within
     its tolerance, else predicted again from that sum (at least one level finer), down to
     `finest_bound_lsb`. A figure's stated uncertainty is that sum; figures still over their
     tolerance at the finest bound are reported, never hidden.
The probe's work (the coarser bounds') is kept in the cache (a re-run replays the same decisions).

rule = "per_pixel" is the former rule: every reference at the [reference] bound, whatever the figures.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from provenance import task_key
from study.engine.rounds import FigureKey, InstantKey, Over, TestKey, instant_levels
from study.metrics import uncertainty as U


MEAN = U.MEAN       # a metric's mean over a sequence's frames: "mse_mean", ...


def figures_of(res, means: bool = False) -> dict:
    """(label, frame, metric) -> (value, halves' uncertainty) of every finite figure of a
    TestResult (the temporal RMS under frame None). `means` (a ghosting test): each metric's mean
    over the frames too, under frame None as `metric + MEAN`, its uncertainty pooled over the
    frames (uncertainty.pooled: the frames' references are independent renders), where every
    frame has the figure."""
    out = {}
    for l, per in res.per_frame.items():
        for f, figs in per.items():
            us = res.uncertainty.get(l, {}).get(f, {})
            out.update({(l, f, m): (v, us.get(m) or 0.0) for m, v in figs.items() if v is not None and math.isfinite(v)})
        if means and per:
            for m in set.intersection(*(set(figs) for figs in per.values())):
                got = [out.get((l, f, m)) for f in per]
                if all(g is not None for g in got):
                    out[(l, None, m + MEAN)] = (math.fsum(v for v, _ in got) / len(got), U.pooled([u for _, u in got]))
        t = res.temporal.get(l)
        if t is not None and math.isfinite(t):
            out[(l, None, "temporal")] = (t, res.temporal_u.get(l) or 0.0)
    return out


def printed(protocol, metric: str) -> bool:
    """Whether a test under `protocol` prints `metric` (Protocol.figures; the temporal RMS always; a
    mean over frames where the frames' figure is): a figure no table prints sets no bound
    (figures.json still states its uncertainty)."""
    m = metric.removesuffix(MEAN)
    return protocol.figures is None or m in protocol.figures or m == "temporal"


def over_tolerance(figures: dict, tolerances: dict) -> list[Over]:
    """An Over (its key, uncertainty and tolerance) for every figure of a `figures_of` dict whose
    reference uncertainty exceeds its tolerance, worst first."""
    out = [Over(*k, u, tol) for k, (v, u) in figures.items()
           for tol in [U.excess(k[-1], v, u, tolerances)] if tol is not None]
    return sorted(out, key=lambda x: -(x[-2] / x[-1] if x[-1] else math.inf))


MARGIN = 1.5      # a figure's halves' uncertainty is one draw (about 2 sd, with a spread): aim below


def drift(now: dict, before: dict, tolerances: dict, scale: float = 1.0) -> tuple[dict, list]:
    """What the halves cannot see: a bias both halves share, which shrinks as the bound does. The
    change of each figure from a coarser bound, beyond what the two references' own noise explains
    (their halves' uncertainties), times `scale` = b / (b0 - b) estimates what is left of it at the
    bound b (exactly, if it shrinks in proportion to the bound). Returns ((label, frame, metric) ->
    that estimate, the figures whose estimate is over their tolerance, as over_tolerance lists them)."""
    change, over = {}, []
    for k, (v, u) in now.items():
        if k in before:
            v0, u0 = before[k]
            d = max(0.0, abs(v - v0) - u - u0) * scale
            change[k] = d
            tol = U.tolerance(k[-1], v, tolerances)
            if tol is not None and d > tol:
                over.append(Over(*k, d, tol))
    return change, over


def levels_asked(u: float, tol: float | None) -> int:
    """How many levels finer a figure of uncertainty u asks for to come within tol: u falls in
    proportion to the bound, so log2(u x MARGIN / tol), rounded up (0 with no scale to ask by: a
    relative tolerance on a figure of 0, or no uncertainty)."""
    if not tol or tol <= 0 or not u:
        return 0
    return math.ceil(math.log2(u * MARGIN / tol))


def level_at(levels: dict, test: tuple, t) -> int:
    """The level of a test's references at instant t: its own (an InstantKey) where an instant was
    refined alone, else the test's."""
    return levels.get(InstantKey(*test, t), levels.get(test, 0))


class Decision(NamedTuple):
    """One round of the rule: the instants to refine, the tests judged, and the state after it (new
    dicts; decide's arguments are left as they were)."""
    finer: dict                   # TestKey -> {t: the level to render next} (t None: the test as a whole)
    judged: set                   # the tests judged this round
    over: dict                    # TestKey -> its figures over tolerance, their uncertainty the drift included
    drifts: dict                  # TestKey -> FigureKey -> drift
    before: dict                  # TestKey -> ({t: bound}, figures) this round judged it at


def decide(now: dict, before: dict, levels: dict, precision, over: dict | None = None, drifts: dict | None = None,
           instants: dict | None = None) -> Decision:
    """One round of the rule, instant by instant. `now`: test -> its figures ((value, halves'
    uncertainty) by (protocol, label, frame, metric), as figures_of gives with the protocol
    prefixed); `instants`: test -> (label, frame) -> the scene time whose reference judges that
    frame (a figure of no frame, the temporal RMS, depends on every instant of the test);
    `levels`: test -> level, test + (t,) -> an instant's own level; `before`: test -> ({t: bound},
    figures) of the round before. A figure is refined where its own instants are: a
    ghosting test whose FLIP of two frames is over renders those two frames' references again,
    not the sequence's (at 320x180, 22 of hairball_rotating_lit's 24 frames stay at 1 LSB rather
    than 0.5: 4x fewer samples each). A test none of whose bounds changed is left as decided; for
    the others its figures over tolerance (their uncertainty the drift included) and its drifts
    are decided anew. Returns a Decision: `over`, `drifts` and `before` are copies of the
    arguments with the tests judged this round replaced."""
    instants = instants or {}
    finer, judged = {}, set()
    before, over = dict(before), dict(over or {})
    drifts = {k: dict(v) for k, v in (drifts or {}).items()}
    most = precision.levels()
    for k in sorted(now):
        where = instants.get(k, {})
        every = sorted(set(where.values()), key=repr) or [None]
        lv = {t: level_at(levels, k, t) for t in every}
        bounds = {t: precision.bound(lv[t]) for t in every}
        if k in before and before[k][0] == bounds:
            continue                       # not refined this round: as decided before
        judged.add(k)
        prev_bounds, prev = before.get(k, ({}, {}))
        kept = drifts.setdefault(k, {})
        figs = {}
        for f, (v, u) in now[k].items():
            f = FigureKey(*f)
            ts = _instants_of(f, where, every)
            changed = [t for t in ts if t in prev_bounds and prev_bounds[t] != bounds[t]]
            if changed and f in prev:      # what both halves share: the change from the coarser bound
                scale = max(bounds[t] / (prev_bounds[t] - bounds[t]) for t in changed)
                v0, u0 = prev[f]
                kept[f] = max(0.0, abs(v - v0) - u - u0) * scale
            figs[f] = (v, u + kept.get(f, 0.0))
        over[k] = over_tolerance(figs, precision.tolerances)
        want: dict = {}
        for f, (v, u) in figs.items():
            ts = _instants_of(f, where, every)
            tol = U.tolerance(f.metric, v, precision.tolerances)
            first = all(lv[t] == 0 for t in ts) and precision.confirm
            is_over = tol is not None and u > tol
            if not (is_over or first):
                continue
            ask = max(1, levels_asked(u, tol))
            base = min(lv[t] for t in ts)  # a figure of many instants: its coarsest ones set its noise
            for t in ts:
                want[t] = max(want.get(t, lv[t]), min(most, base + ask))
        # a figure under its tolerance still asks, at an instant refined anyway, for what it needs
        for f, (v, u) in figs.items():
            ts = [t for t in _instants_of(f, where, every) if t in want]
            tol = U.tolerance(f.metric, v, precision.tolerances)
            if ts and len(ts) == len(_instants_of(f, where, every)):
                ask = levels_asked(u, tol)
                for t in ts:
                    want[t] = max(want[t], min(most, lv[t] + ask))
        step = {t: n for t, n in want.items() if n > lv[t]}
        if step:
            finer[k] = step
        before[k] = (bounds, now[k])
    return Decision(finer, judged, over, drifts, before)


def _instants_of(figure: FigureKey, where: dict, every: list) -> list:
    """The instants a figure is judged against: its frame's, or every instant of the test for a
    figure of no frame (or a frame no instant is known for)."""
    t = where.get((figure.label, figure.frame), _NONE) if figure.frame is not None else _NONE
    return every if t is _NONE else [t]


_NONE = object()


def to_record(levels: dict, tried: dict, over: dict, drifts: dict) -> dict:
    """A study's decisions as JSON: each test's final level, the bounds it was rendered to, its
    figures over tolerance and its drifts. A study whose probe plans the same tasks under the same
    rule decides the same (every task is deterministic), so it replays these instead of planning
    and reading every round again."""
    return {"tests": [{"test": list(k), "level": levels.get(k, 0), "tried": list(tried[k]),
                       "instants": sorted([[t, n] for t, n in instant_levels(levels, k).items()]),
                       "over": [list(x) for x in over.get(k, [])],
                       "drift": [[*f, d] for f, d in drifts.get(k, {}).items()]} for k in sorted(tried)]}


def from_record(rec: dict) -> tuple[dict, dict, dict, dict]:
    """(levels, tried, over, drifts) of a to_record record."""
    levels, tried, over, drifts = {}, {}, {}, {}
    for t in rec["tests"]:
        k = TestKey(*t["test"])
        levels[k], tried[k] = int(t["level"]), list(t["tried"])
        levels.update({InstantKey(*k, i): int(n) for i, n in t.get("instants", [])})
        over[k] = [Over(*x) for x in t["over"]]
        drifts[k] = {FigureKey(*d[:-1]): d[-1] for d in t["drift"]}
    return levels, tried, over, drifts


def bounds_text(bounds: dict) -> str:
    """'1' for one bound (bound -> instants at it), '1 (22 instants), 0.5 (2)' for several, the
    coarsest first.

    >>> bounds_text({0.5: 2, 1.0: 22}), bounds_text({2.0: 1, 1.0: 3}), bounds_text({4.0: 5})
    ('1 (22 instants), 0.5 (2)', '2 (1 instant), 1 (3)', '4')
    """
    if len(bounds) == 1:
        return f"{next(iter(bounds)):g}"
    return ", ".join(f"{b:g} ({n}{(' instant' if n == 1 else ' instants') if i == 0 else ''})"
                     for i, (b, n) in enumerate(sorted(bounds.items(), reverse=True)))


def _settled_path(store, precision, test: tuple, probe_refs: list):
    key = task_key("precision-settled", {"test": list(test), "references": probe_refs, "precision": repr(precision)},
                   code=["study.engine.precision"])
    return store.record_path("precision", "settled", key), key


def settle(store, precision, probes: dict, levels: dict) -> None:
    """Each test's final level and its instants' own, filed under its probe references (test ->
    their keys; what `settled` reads)."""
    for k, refs in probes.items():
        path, key = _settled_path(store, precision, k, refs)
        rec = {"level": levels.get(k, 0), "instants": sorted([[t, n] for t, n in instant_levels(levels, k).items()])}
        old = store.load_record(path, key) or {}
        if (old.get("level"), old.get("instants", [])) != (rec["level"], rec["instants"]):
            store.save_record(path, key, rec)


def settled(store, precision, probes: dict) -> dict:
    """Levels (as `decide` reads them) an earlier study settled the tests at, for the tests one did."""
    out = {}
    for k, refs in probes.items():
        rec = store.load_record(*_settled_path(store, precision, k, refs))
        if rec is not None and (rec.get("level", 0) > 0 or rec.get("instants")):
            out[TestKey(*k)] = int(rec.get("level", 0))
            out.update({InstantKey(*k, t): int(n) for t, n in rec.get("instants", [])})
    return out


def decisions(store, precision, plan, agreement: bool) -> dict:
    """Where a study's precision decisions are recorded: keyed by the probe's figures (every
    test's metrics keys: scene, techniques, code, references' settings), the rule and the code
    that decides; with the record of an earlier study of that key, if one is there."""
    key = task_key("precision", {"precision": repr(precision), "agreement": agreement,
                                 "metrics": sorted(k for t in plan.tests for k in t.metrics_keys.values())},
                   code=["study.engine.precision", "study.engine.runner", "study.engine.rounds"])
    path = store.record_path("precision", "decisions", key)
    return {"store": store, "path": path, "key": key, "replayed": store.load_record(path, key)}


def inputs_key(study, specs, configs, flags: list) -> str:
    """What a study's probe plan is made from, keyed without planning it: the profile (protocols,
    settings, precision), each scene's content, each column's technique and the code of what
    plans, renders, runs and judges. The same inputs plan the same probe, whose decisions an
    earlier study recorded (`decisions`): a no-op study then plans its final round alone."""
    from study.engine.plan import CODE
    from study.engine.tasks import load_scene
    cols = [*configs, *flags[1], *flags[3]]             # the columns, the sweep's and the sharpen sweep's
    return task_key("precision-inputs", {"profile": repr(study.profile), "flags": [bool(f) for f in flags],
                                         "scenes": [(s, load_scene(s).content_hash) for s in specs],
                                         "columns": [(c.label, c.key_data()) for c in cols]},
                    code=[*{c.code() for c in cols}, *CODE["run"], *CODE["metrics"], *CODE["reference"],
                          "study.engine.plan", "study.engine.precision", "study.engine.runner", "study.engine.rounds"])


def recall(store, inputs: str) -> dict | None:
    """The decisions record (as `decisions` returns it) an earlier study of these inputs made."""
    rec = store.load_record(store.record_path("precision", "inputs", inputs), inputs)
    if rec is None:
        return None
    path = store.record_path("precision", "decisions", rec["decisions"])
    replayed = store.load_record(path, rec["decisions"])
    return None if replayed is None else {"store": store, "path": path, "key": rec["decisions"], "replayed": replayed}


def remember(store, inputs: str | None, decisions_key: str) -> None:
    """File which decisions record these inputs' probe is keyed to (what `recall` reads)."""
    path = store.record_path("precision", "inputs", inputs) if inputs else None
    if path is not None and (store.load_record(path, inputs) or {}).get("decisions") != decisions_key:
        store.save_record(path, inputs, {"decisions": decisions_key})
