"""A study: plan its tasks (study.engine.plan), execute them (study.engine.execute), measure costs serially
(study.engine.costs), and gather the results the report turns into tables and figures.

Every artefact is keyed by what produced it (provenance.task_key): a run by the scene's content,
the protocol's schedule, the resolution, the technique's parameters and code (and the references
when the technique works on display images); metrics by the run and reference keys and the metric
code. A second study with nothing changed plans no task and only re-reads small records.
"""
from __future__ import annotations

import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

from provenance import code_snapshot
from references import ReferenceCache
from references.settings import SE_BOUND_LSB
from scenes import ResolvedScene

from study.config.profile import Profile, get_profile
from study.config.protocols import Protocol
from study.config.techniques import TechniqueConfig
from study.engine.execute import Executor, Session
from study.engine.plan import Planner
from study.config.precision import Precision
from study.engine import disk as D
from study.engine import precision as P
from study.engine import supersede as S
from study.engine.precision import decide, figures_of
from study.engine.rounds import FigureKey, InstantKey, Progress, Request, Round, TestKey, log_judged
from study.engine.rounds import seeded_early as _seeded_early
from study.engine.store import Store
from study.engine.stopping import StudyStopped, computed_counts, stop
from study.engine.results import Artefacts, StudyResults, TestResult, run_records, test_result, view, with_drift
from study.engine.prune import prune_runs
from study.engine.tasks import Context, display_of, load_scene


def is_animated(scene: ResolvedScene) -> bool:
    f = set(scene.desc.features())
    return scene.desc.frames > 1 and bool(f & {"moving_object", "moving_camera", "camera_cut"})


class Study:
    def __init__(self, profile: str | Profile = "quick", cache_root: Path | None = None, progress: bool = True,
                 log=None, executor: Executor = Executor(), deadline: float | None = None):
        self.profile: Profile = get_profile(profile)
        # no task starts after it (study.engine.execute.now(); None: none): run() raises StudyStopped
        self.deadline = deadline
        self.cache = ReferenceCache(cache_root)
        self.progress = progress
        self.log = log or (lambda m: print(m, file=sys.stderr))
        self.executor = executor
        self.ctx = Context(str(self.cache.root), executor.threads)
        self.ref_settings = dict(self.profile.ref_settings)
        self.precision: Precision = self.profile.precision
        self.display_settings = self.precision.display_settings(self.ref_settings)
        # TestKey -> the test's precision level, InstantKey -> an instant's own where it was
        # refined alone (study.engine.precision; the precision loop's state sets them each round)
        self.levels: dict[tuple, int] = {}
        self.drifts: dict = {}
        self._tests: dict = {}        # (scene name, protocol name) -> its Test in the latest plan

    def settings_for(self, name: str, protocol: str | None = None, t: int | None = None) -> dict:
        """The settings of a test's references at its current precision level, at instant t that
        instant's own (the scene's static test when no protocol is named: frame 0's reference, the
        agreement, the costs)."""
        return self.precision.settings(self.ref_settings, self.level_of(name, protocol, t))

    def level_of(self, name: str, protocol: str | None = None, t: int | None = None) -> int:
        """A test's precision level, at instant t that instant's own. The ghosting protocols judge
        the same instants: one reference each, at the finest level any of them asks for. The static
        test keeps its own (its controls ask for finer bounds every round: see the README)."""
        k = TestKey(name, protocol or self.profile.static.name)
        base = self.levels.get(k, 0)
        if t is None:
            return base
        own = P.level_at(self.levels, k, t)
        ghosting = [p.name for p in self.profile.ghosting]
        if k.protocol in ghosting:
            own = max([own] + [self.levels.get(InstantKey(name, p, t), 0) for p in ghosting])
        return max(base, own)

    def bound_of(self, name: str, protocol: str | None = None, t: int | None = None) -> float:
        """The per-pixel bound a test's references are rendered to now (a study file may leave it
        to the cache's default)."""
        return self.settings_for(name, protocol, t).get("se_bound_lsb", SE_BOUND_LSB)

    def bounds_of(self, name: str, protocol: str, instants) -> dict:
        """bound -> how many of the instants are rendered to it."""
        return dict(Counter(self.bound_of(name, protocol, t) for t in instants))

    def resolution(self, scene: ResolvedScene) -> tuple[int, int]:
        r = self.profile.resolution
        return tuple(r) if isinstance(r, (tuple, list)) else scene.resolution(r)

    def reference(self, scene: ResolvedScene, t: int, w: int, h: int, protocol: str | None = None):
        """Instant t's reference as the plan rendered it: with its test's settings there, which say
        where its chain of reused frames starts (reuse_chain.chain_reuse; other settings would render the
        chain again); an instant no test judges, whole."""
        test = self._tests.get((scene.name, protocol or self.profile.static.name))
        settings = test.ref_settings_at.get(t) if test is not None else None
        if settings is None:
            settings = {k: v for k, v in self.settings_for(scene.name, protocol, t).items() if k != "reuse"}
        return self.cache.get(scene, t, w, h, **settings)[0]

    def display(self, scene: ResolvedScene, t: int, w: int, h: int):
        """Frame t's display transform (study.engine.tasks.display_of)."""
        return display_of(self.cache, scene, t, w, h, self.display_settings)

    def _reference_of(self, scenes):
        """scene name, t, w, h[, protocol] -> its Reference (the reporting's way to a reference's pixels)."""
        by_name = {scene.name: scene for _, scene in scenes}
        return lambda name, t, w, h, protocol=None: self.reference(by_name[name], t, w, h, protocol)

    # -- the whole study ----------------------------------------------------------------------------
    def plan(self, specs: list[str], configs: list[TechniqueConfig], agreement: bool = True,
             sweep: tuple = (), ghosting: bool = True, final: bool | frozenset = True, sharpen: tuple = (),
             prune: bool = True):
        """The study's tests and the tasks it must compute: (plan, scenes, statics, ghosts, sweeps,
        sharpen sweeps). `sharpen`: the sharpen sweep's configs (study.config.profile.sharpen_sweep_configs),
        judged at the thesis's history on the profile's sharpen_sweep_scenes.
        `final`: the study's last round, whose references are final: the video metric's and the
        agreement's tasks too; or the tests ((scene, protocol)) already settled, theirs alone."""
        scenes = [(spec, load_scene(spec)) for spec in specs]
        protos = [self.profile.static, *self.profile.ghosting]
        ref_of = {(scene.name, p.name): self.settings_for(scene.name, p.name) for _, scene in scenes for p in protos}
        ref_of.update({k: self.settings_for(*k) for k in self.levels if isinstance(k, InstantKey)})
        planner = Planner(self.ctx, self.ref_settings, self.profile.agreement_samples if agreement else None, ref_of,
                          self.display_settings, video=self.profile.video, video_final=final, prune=prune)
        statics, ghosts, sweeps, sharpens = [], [], [], []
        # at the thesis's history alone; named as the static test, whose references it shares
        st = self.profile.static
        sharpen_proto = Protocol(st.name, "static", history=self.profile.thesis_history,
                                 checkpoints=(self.profile.thesis_history,))
        for spec, scene in scenes:
            w, h = self.resolution(scene)
            cols, runs = self.profile.tests_of(spec, scene.name, configs)    # a scene group's own
            # a run keeps, once judged, the frames the report reads (static views, ghosting sliders)
            every = self.profile.keep_frames == "all"
            if runs(st.name):
                statics.append(planner.add_test(spec, scene, self.profile.static, cols, w, h,
                                                 maps=tuple(self.profile.static_views.values()),
                                                 keep="all" if every else "maps"))
            if ghosting and is_animated(scene):
                skip = self.profile.ghosting_techniques_skip      # registry names or column labels
                gconf = [c for c in cols if c.name not in skip and c.label not in skip]
                for p in (q for q in self.profile.ghosting if runs(q.name)):
                    ghosts.append(planner.add_test(spec, scene, p, gconf, w, h, maps="none",
                                                   keep="all" if every else "shown"))
            if sweep and scene.name in self.profile.sweep_scenes:
                proto = self.profile.ghosting[0] if is_animated(scene) else self.profile.static
                sweeps.append(planner.add_test(spec, scene, proto, list(sweep), w, h, maps="none",
                                               keep="all" if every else "none"))
            if sharpen and scene.name in self.profile.sharpen_sweep_scenes:
                sharpens.append(planner.add_test(spec, scene, sharpen_proto, list(sharpen), w, h, maps="none",
                                                 keep="none"))
            if planner.is_final((scene.name, st.name)):
                planner.add_agreement(spec, scene, w, h, st.name)
        self.planner = planner
        self._tests = {(test.scene, test.protocol.name): test for test in statics + ghosts}
        return planner.plan, scenes, statics, ghosts, sweeps, sharpens

    def run(self, specs: list[str], configs: list[TechniqueConfig], agreement: bool = True,
            sweep: tuple = (), ghosting: bool = True, sharpen: tuple = (), seeded: bool = False) -> StudyResults:
        """Plan, execute and gather; under the figures' precision rule, again for every test with a
        figure over its tolerance (or only probed), its references at the bound its figures ask for,
        until none is or the finest bound is reached (study.engine.precision). `seeded`: a test an
        earlier study settled (the same references) starts at the bound it settled at, not at the
        probe (an A/B comparison: its new column is judged there, and refined only if over)."""
        ask = Request(specs, configs, agreement, sweep, ghosting, sharpen, seeded)
        state = self.recall_decisions(ask)
        # the round before (or what a killed study's last round read): what a finer one replaced is removed
        self._last = getattr(self, "_resumed", None)
        with Session(self.executor, self.log, self.deadline) as session:     # one cluster for every round
            while not state.finished:
                state, rnd = self.plan_round(ask, state)
                self._last = S.before_round(self, self._last, rnd)
                state = self.execute_round(session, rnd, state)
                if not state.finished:
                    state = self.decide_next(ask, rnd, state, self.judge_round(rnd, state))
                    S.file_progress(self, state, rnd)
        self.file_decisions(state)
        return self.gather(rnd, state, session)

    # -- the precision loop's steps (study.engine.rounds) ----------------------------------------------
    def _adopt(self, state: Progress) -> Progress:
        """The levels and drifts the plan and the results read are the state's."""
        self.levels, self.drifts = state.levels, state.drifts
        return state

    def recall_decisions(self, ask: Request) -> Progress:
        """The state a study starts from: every test at its probe (the levels set on the study), or,
        under the figures' rule, every bound an earlier study of the same inputs decided (its final
        round is then the only one)."""
        figures = self.precision.rule == "figures"
        state = Progress(levels=dict(self.levels), final=not figures)
        if figures:
            inputs = P.inputs_key(self, ask.specs, ask.configs,
                                  [ask.agreement, ask.sweep, ask.ghosting, ask.sharpen, ask.seeded])
            state = replace(state, inputs=inputs)
            if memo := P.recall(Store(self.cache.root), inputs):      # no probe plan needed
                levels, tried, over, drifts = P.from_record(memo["replayed"])
                self.log("precision: every test's bound as decided by an earlier study of the same inputs")
                state = replace(state, levels=levels, tried=tried, over=over, drifts=drifts, memo=memo, final=True)
            elif not self.profile.keep_superseded and (got := S.resume(self, inputs)):
                state = replace(state, **got)      # a killed study's coarser references are gone
        return self._adopt(state)

    def plan_round(self, ask: Request, state: Progress) -> tuple[Progress, Round]:
        """This round's plan: planned again while the plan itself changes what to plan (the disk
        prunes more tests' runs; the probe's plan finds an earlier study's decisions)."""
        rnd = self._plan_once(ask, state)
        state, again = self._revise(ask, rnd, state)
        while again:
            rnd = self._plan_once(ask, state)
            state, again = self._revise(ask, rnd, state)
        return state, rnd

    def _plan_once(self, ask: Request, state: Progress) -> Round:
        figures = self.precision.rule == "figures"
        self._adopt(state)
        with code_snapshot():
            return Round.of(self.plan(ask.specs, ask.configs, ask.agreement, ask.sweep, ask.ghosting,
                                      final=state.final or state.early, sharpen=ask.sharpen,
                                      prune=True if not figures else state.pruned))

    def _revise(self, ask: Request, rnd: Round, state: Progress) -> tuple[Progress, bool]:
        """(the state, whether to plan again) once a plan is made: which tests' runs the disk keeps
        whole while they refine (each round: finer references take room), and, for the probe's plan,
        whether a study decided from it before."""
        figures = self.precision.rule == "figures"
        whole = figures and self.profile.runs_while_refining == "whole"    # else every test's runs are pruned once judged
        freed = S.freeable(self, getattr(self, "_last", None), rnd)      # superseded, removed before it renders
        pruned = D.fit(D.needs(rnd.plan), D.free_bytes(self.cache.root) + freed, whole, self.cache.root, state.pruned,
                       self.log, D.budget_left(self.profile.disk_budget_gb, self.cache.root, freed))
        if figures and pruned != state.pruned:
            return replace(state, pruned=pruned), True          # their metrics prune their runs
        if not figures or state.memo is not None:
            return state, False
        memo = P.decisions(Store(self.cache.root), self.precision, rnd.plan, ask.agreement)
        probes = {TestKey(t.scene, t.protocol.name): sorted(t.reference_tasks.values()) for t in rnd.judged}
        state = replace(state, memo=memo, probes=probes)
        seeds = P.settled(memo["store"], self.precision, probes) if ask.seeded and not memo["replayed"] else {}
        if seeds:
            seeded_tests = {x.test if isinstance(x, InstantKey) else x for x in seeds}
            self.log(f"precision: {len(seeded_tests)} of {len(probes)} tests start at the bound an earlier study settled")
            # their agreement and video are planned now, beside the new columns' runs: an earlier
            # study's bound usually holds (else they are made again at the finer one)
            early = _seeded_early(probes, seeded_tests, {p.name for p in self.profile.ghosting})
            return replace(state, levels={**state.levels, **seeds}, early=early), True
        if memo["replayed"]:
            levels, tried, over, drifts = P.from_record(memo["replayed"])
            self.log("precision: every test's bound as decided by an earlier study of the same tasks")
            return replace(state, levels=levels, tried=tried, over=over, drifts=drifts, final=True), True
        return state, False

    def execute_round(self, session: Session, rnd: Round, state: Progress) -> Progress:
        """Compute the round's plan; the round's results are the state's last. A round whose
        references are final is the study's last."""
        tried = {k: list(v) for k, v in state.tried.items()}
        for k in sorted(rnd.instants):
            b, seen = min(self.bounds_of(*k, set(rnd.instants[k].values())) or [self.bound_of(*k)]), tried.setdefault(k, [])
            if not seen or seen[-1] != b:
                seen.append(b)
        plan, rounds = rnd.plan, list(state.rounds)
        counts = plan.counts()
        if plan.tasks:
            todo = plan.to_compute()
            self.log(f"study: {sum(todo.values())} tasks to compute ({', '.join(f'{k} {n}' for k, n in sorted(todo.items()))})"
                     f", {plan.complete()} complete; executor: {self.executor.describe()}")
        t0, spent = time.perf_counter(), Counter(session.task_seconds)
        if plan.tasks and session.past_deadline():
            stop(rounds, {}, Counter(t.kind for t in plan.tasks.values()))
        results = session.execute(plan, self.progress)
        for key in [k for k, v in results.items() if "records" in v]:   # a metrics or video task: by key
            task = results.pop(key)
            results.update({mkey: {"kind": task["kind"], "key": mkey, **rec} for mkey, rec in task["records"].items()})
        if session.not_started:   # the deadline came: what finished is cached, nothing is decided
            stop(rounds, results, session.not_started)
        if plan.tasks:
            spent, reused = session.task_seconds - spent, sum(v.get("frames_reused", 0) for v in results.values())
            self.log(f"study: round {len(rounds) + 1} took {time.perf_counter() - t0:.1f} s wall; task seconds "
                     + ", ".join(f"{k} {v:.1f}" for k, v in sorted(spent.items()))
                     + (f"; {reused} technique-frames' figures taken from an earlier round's" if reused else ""))
        return replace(state, tried=tried, rounds=state.rounds + ((counts, results),), finished=state.final)

    def judge_round(self, rnd: Round, state: Progress) -> dict:
        """TestKey -> the figures that bound its precision (FigureKey -> (value, halves'
        uncertainty)) from the round's results: those a test prints, of columns and figures not exempt
        (study.config.precision.Precision.exempts)."""
        results, now = state.rounds[-1][1], {}
        for t in rnd.judged:       # a ghosting test: its means over frames too
            figs = figures_of(self._result(t, results, {}), means=t.protocol.kind == "ghosting")
            now.setdefault(TestKey(t.scene, t.protocol.name), {}).update(
                {FigureKey(t.protocol.name, *k): v for k, v in figs.items()
                 if not self.precision.exempts(t.spec, t.protocol.name, k[0], k[-1]) and P.printed(t.protocol, k[-1])})
        return now

    def decide_next(self, ask: Request, rnd: Round, state: Progress, now: dict) -> Progress:
        """What the next round renders (study.engine.precision.decide): finer references where the
        figures ask for them; where none do, one more round only for what the final references
        feed (the agreement, the video metric) that no round has planned yet, else the study is done."""
        levels = {**state.levels, **{InstantKey(*k, t): self.level_of(*k, t)
                                     for k in rnd.instants for t in rnd.instants[k].values()}}
        d = decide(now, state.before, levels, self.precision, state.over, state.drifts, rnd.instants)
        # a settled test's runs drop the frames the report does not read; the others stay
        # whole, judged again at the finer bound without being re-made
        prune_runs(self.planner, lambda k: k not in d.finer)
        state = self._adopt(replace(state, over=d.over, drifts=d.drifts, before=d.before))
        log_judged(self.log, self.precision, d.judged, d.finer, state, rnd, self.bounds_of)
        if not d.finer:
            if (not ask.agreement and not self.profile.video.on) or all(k in state.early for k in rnd.instants):
                return replace(state, finished=True)   # nothing asks for the final references, or planned already
            state = replace(state, final=True)   # one more round: what the last tests settled ask for
        # settled: not refined, nor is a ghosting protocol of its scene (they share the instants' references)
        ghost = {p.name for p in self.profile.ghosting}
        moving = {(s, p) for s, q in d.finer for p in ({q} | (ghost if q in ghost else set()))}
        refined = {TestKey(*k) if t is None else InstantKey(*k, t): n for k, step in d.finer.items() for t, n in step.items()}
        return self._adopt(replace(state, early=frozenset(k for k in rnd.instants if k not in moving),
                                   levels={**state.levels, **refined}))

    def file_decisions(self, state: Progress) -> None:
        """Prune every run to its kept frames and record the decisions (each test's bound, under its
        probe references and under the study's inputs) for a later study to replay or start from."""
        self._adopt(state)
        prune_runs(self.planner, lambda k: True)
        store, memo = Store(self.cache.root), state.memo
        if state.probes is not None:
            P.settle(store, self.precision, state.probes, state.levels)
        if memo is not None and not memo["replayed"]:
            memo["store"].save_record(memo["path"], memo["key"],
                                      P.to_record(state.levels, state.tried, state.over, state.drifts))
        if memo is not None:
            P.remember(memo["store"], state.inputs, memo["key"])
        S.forget_progress(store, state.inputs)
        store.save_hashes()

    def gather(self, rnd: Round, state: Progress, session: Session) -> StudyResults:
        """The study's results from every round's (a task's first round is the one that computed
        it; later ones find it cached) and the last round's plan."""
        results: dict = {}
        for _, r in state.rounds:
            for k, v in r.items():
                results.setdefault(k, v)
        counts: dict = {}
        for c, _ in state.rounds:
            for k, n in c.items():
                counts[k] = counts.get(k, 0) + n
        plan, scenes, statics, ghosts, sweeps, sharpens = (rnd.plan, rnd.scenes, rnd.statics, rnd.ghosts, rnd.sweeps,
                                                           rnd.sharpens)

        by_name = {scene.name: scene for _, scene in scenes}
        out = StudyResults(artefacts=Artefacts(self.cache.root), reference=self._reference_of(scenes),
                           display=lambda name, t, w, h: self.display(by_name[name], t, w, h),
                           thesis_history=self.profile.thesis_history, tolerances=self.precision.tolerances)
        out.precision, every = {}, {(t.scene, t.protocol.name): set(t.reference_tasks) for t in statics + ghosts + sweeps}
        for (name, proto), seen in sorted(state.tried.items()):
            bounds = self.bounds_of(name, proto, every.get((name, proto)) or [None])
            out.precision.setdefault(name, {})[proto] = {"bound_lsb": min(bounds), "rule": self.precision.rule,
                                                         "bounds": {f"{b:g}": n for b, n in sorted(bounds.items())},
                                                         "over": state.over.get((name, proto), []), "rounds": seen}
        n_runs = sum(len(t.configs) for t in statics + ghosts + sweeps + sharpens)
        out.stats = {**computed_counts(results), "tasks": counts, "task_seconds": dict(session.task_seconds),
                     "task_seconds_by_scene": session.seconds_by_scene()}
        out.stats["runs_cached"] = max(0, n_runs - out.stats["runs_computed"])
        costs = self._costs(scenes, statics, results)
        for spec, scene in scenes:
            w, h = self.resolution(scene)
            ref, cached = self.cache.get(scene, 0, w, h, **self.settings_for(scene.name))
            out.references[scene.name] = ref
            out.stats["references_rendered"] += not cached   # a damaged file found only now, re-made
            if scene.name in plan.agreements:
                out.agreements[scene.name] = results[plan.agreements[scene.name]]["data"]
        for t in statics:
            full = with_drift(self._result(t, results, costs), self.drifts)
            out.statics.append(full)
            for label, n in self.profile.static_views.items():
                out.views.setdefault(label, []).append(view(full, label, n))
        for t in ghosts:
            out.ghosts.setdefault(t.protocol.name, []).append(with_drift(self._result(t, results, costs), self.drifts))
        out.sweeps = [with_drift(self._result(t, results, costs), self.drifts) for t in sweeps]
        out.sharpen_sweeps = [self._result(t, results, {}) for t in sharpens]
        return out

    def _records(self, test) -> dict:
        return run_records(self.cache.root, test)

    def _result(self, test, results: dict, costs: dict) -> TestResult:
        return test_result(self.cache.root, test, results, costs)

    # -- costs: serial, after everything else ---------------------------------------------------------
    def _costs(self, scenes, statics, results) -> dict:
        from study.engine import costs as C
        return C.measure_study(self.cache.root, scenes, statics, self._records, self.display, self.progress)


__all__ = ["Study", "StudyResults", "StudyStopped", "TestResult", "is_animated"]
