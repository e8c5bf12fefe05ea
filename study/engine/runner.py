"""A study: plan its tasks (study.engine.plan), execute them (study.engine.execute), measure costs serially
(study.engine.costs), and gather the results the report turns into tables and figures.

Every artefact is keyed by what produced it (provenance.task_key): a run by the scene's content,
the protocol's schedule, the resolution, the technique's parameters and code (and the references
when the technique works on display images); metrics by the run and reference keys and the metric
code. A second study with nothing changed plans no task and only re-reads small records.
"""
from __future__ import annotations

import math
import time
from collections import Counter
import sys
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
from study.engine.precision import decide, figures_of
from study.engine.stopping import StudyStopped, computed_counts, stop
from study.engine.results import Artefacts, StudyResults, TestResult, view
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
        # (scene name, protocol name) -> the test's precision level, + (scene time,) -> an instant's
        # own where it was refined alone (study.engine.precision)
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
        k = (name, protocol or self.profile.static.name)
        base = self.levels.get(k, 0)
        if t is None:
            return base
        own = P.level_at(self.levels, k, t)
        ghosting = [p.name for p in self.profile.ghosting]
        if k[1] in ghosting:
            own = max([own] + [self.levels.get((name, p, t), 0) for p in ghosting])
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
        ref_of.update({k: self.settings_for(*k) for k in self.levels if len(k) == 3})
        planner = Planner(self.ctx, self.ref_settings, self.profile.agreement_samples if agreement else None, ref_of,
                          self.display_settings, video=self.profile.video, video_final=final, prune=prune)
        statics, ghosts, sweeps, sharpens = [], [], [], []
        # at the thesis's history alone; named as the static test, whose references it shares
        st = self.profile.static
        sharpen_proto = Protocol(st.name, "static", history=self.profile.thesis_history,
                                 checkpoints=(self.profile.thesis_history,))
        for spec, scene in scenes:
            w, h = self.resolution(scene)
            # a run keeps, once judged, the frames the report reads (static views, ghosting sliders)
            every = self.profile.keep_frames == "all"
            statics.append(planner.add_test(spec, scene, self.profile.static, configs, w, h,
                                             maps=tuple(self.profile.static_views.values()),
                                             keep="all" if every else "maps"))
            if ghosting and is_animated(scene):
                skip = self.profile.ghosting_techniques_skip      # registry names or column labels
                gconf = [c for c in configs if c.name not in skip and c.label not in skip]
                for p in self.profile.ghosting:
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
        rounds, tried, over, before = [], {}, {}, {}    # over: (scene, protocol) -> figures over at its bound
        self.drifts = {}              # (scene, protocol) -> (protocol, label, frame, metric) -> drift
        figures = self.precision.rule == "figures"
        # the agreement (64-256 raster frames a scene) and the video metric against the final references:
        # a test's as soon as it is settled (`early`: its tasks fill the rounds other tests still refine in)
        settled, early = not figures, frozenset()
        memo, probes = None, None     # the record of this study's decisions (figures rule)
        pruned = None                 # the tests whose runs are pruned once judged (study.engine.disk)
        from study.engine.store import Store
        inputs = P.inputs_key(self, specs, configs, [agreement, sweep, ghosting, sharpen, seeded]) if figures else None
        if inputs and (memo := P.recall(Store(self.cache.root), inputs)):    # no probe plan needed
            self.levels, tried, over, self.drifts = P.from_record(memo["replayed"])
            self.log("precision: every test's bound as decided by an earlier study of the same inputs")
            settled = True
        with Session(self.executor, self.log, self.deadline) as session:     # one cluster for every round
            while True:
                with code_snapshot():
                    plan, scenes, statics, ghosts, sweeps, sharpens = self.plan(specs, configs, agreement, sweep, ghosting,
                                                                      final=settled or early, sharpen=sharpen,
                                                                      prune=True if not figures else pruned or frozenset())
                # which tests' runs the disk keeps whole while they refine (each round: finer references take room)
                was = pruned or frozenset()
                pruned = D.fit(D.needs(plan, self.planner), D.free_bytes(self.cache.root), figures,
                               self.cache.root, was, self.log)
                if figures and pruned != was:
                    continue            # planned again: their metrics prune their runs

                if figures and memo is None:      # the probe's plan: did a study decide from it before?
                    memo = P.decisions(Store(self.cache.root), self.precision, plan, agreement)
                    probes = {(t.scene, t.protocol.name): sorted(t.reference_tasks.values()) for t in statics + ghosts + sweeps}
                    seeds = P.settled(memo["store"], self.precision, probes) if seeded and not memo["replayed"] else {}
                    if seeds:
                        self.levels.update(seeds)
                        seeded_tests = {x[:2] for x in seeds}
                        self.log(f"precision: {len(seeded_tests)} of {len(probes)} tests start at the bound an earlier study settled")
                        # their agreement and video are planned now, beside the new columns' runs: an
                        # earlier study's bound usually holds (else they are made again at the finer one)
                        early = _seeded_early(probes, seeded_tests, {p.name for p in self.profile.ghosting})
                        continue
                    if memo["replayed"]:
                        self.levels, tried, over, self.drifts = P.from_record(memo["replayed"])
                        self.log("precision: every test's bound as decided by an earlier study of the same tasks")
                        settled = True        # the final round alone: plan it
                        continue
                instants: dict = {}       # test -> (label, frame) -> the scene time judging it
                for t in statics + ghosts + sweeps:
                    instants.setdefault((t.scene, t.protocol.name), {}).update(
                        {(label, f): time for label, ft in t.frame_times.items() for f, time in ft.items()})
                for k in sorted(instants):
                    b, seen = min(self.bounds_of(*k, set(instants[k].values())) or [self.bound_of(*k)]), tried.setdefault(k, [])
                    if not seen or seen[-1] != b:
                        seen.append(b)
                counts = plan.counts()
                if plan.tasks:
                    self.log(f"study: {len(plan.tasks)} tasks to compute ({', '.join(f'{k} {n}' for k, n in sorted(counts.items()))})"
                             f", {len(plan.cached)} complete; executor: {self.executor.describe()}")
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
                rounds.append((counts, results))
                if settled:
                    break
                now: dict = {}
                for t in statics + ghosts + sweeps:        # a sweep shares its protocol's references
                    now.setdefault((t.scene, t.protocol.name), {}).update(
                        {(t.protocol.name, *k): v for k, v in figures_of(self._result(t, results, {})).items()
                         if k[0] not in self.precision.exempt and P.printed(t.protocol, k[-1])})
                levels = {**self.levels, **{(*k, t): self.level_of(*k, t) for k in instants for t in instants[k].values()}}
                finer, judged = decide(now, before, levels, self.precision, over, self.drifts, instants)
                # a settled test's runs drop the frames the report does not read; the others stay
                # whole, judged again at the finer bound without being re-made
                self.planner.prune_runs(lambda k: k not in finer)
                for k in sorted(judged):
                    every = set(instants[k].values())
                    name, b = f"{k[0]} ({k[1]})", P.bounds_text(self.bounds_of(*k, every))
                    nxt = ""
                    if k in finer:
                        to = Counter(self.precision.bound(n) for n in finer[k].values())
                        nxt = "references again at " + P.bounds_text(to) + (
                            f" ({len(finer[k])} of {len(every)} instants)" if len(finer[k]) < len(every) else "")
                    if not over[k]:
                        if k in finer:
                            self.log(f"precision: {name}: every figure within its tolerance at the probe ({b} LSB); {nxt}, "
                                     "where the figures ask for it and the drift can be measured")
                        elif len(tried.get(k, ())) == 1:
                            first = "probe" if b == f"{self.precision.start_bound_lsb:g}" else "first bound (an earlier study's)"
                            self.log(f"precision: {name}: every figure within its tolerance at its {first} ({b} LSB): settled")
                        continue
                    label, tech, f, m, u, tol = over[k][0]
                    self.log(f"precision: {name}: {len(over[k])} figures over their tolerance at {b} LSB, the worst "
                             f"{m} of {tech} ({label}, frame {f}) +-{u:.3g} > {tol:.3g}; "
                             + (nxt if k in finer else "the finest bound: reported"))
                if not finer:
                    if (not agreement and not self.profile.video.on) or all(k in early for k in instants):
                        break         # nothing asks for the final references, or this round planned it all
                    settled = True    # one more round: what the last tests settled ask for (the rest is cached)
                # settled: not refined, nor is a ghosting protocol of its scene (they share the instants' references)
                ghost = {p.name for p in self.profile.ghosting}
                moving = {(s, p) for s, q in finer for p in ({q} | (ghost if q in ghost else set()))}
                early = frozenset(k for k in instants if k not in moving)
                self.levels.update({k if t is None else (*k, t): n for k, step in finer.items() for t, n in step.items()})
        self.planner.prune_runs(lambda k: True)
        if probes is not None:
            P.settle(Store(self.cache.root), self.precision, probes, self.levels)
        if memo is not None and not memo["replayed"]:
            memo["store"].save_record(memo["path"], memo["key"], P.to_record(self.levels, tried, over, self.drifts))
        if memo is not None:
            P.remember(memo["store"], inputs, memo["key"])
        Store(self.cache.root).save_hashes()
        results: dict = {}
        for _, r in rounds:       # a task's first round is the one that computed it; later ones find it cached
            for k, v in r.items():
                results.setdefault(k, v)
        counts: dict = {}
        for c, _ in rounds:
            for k, n in c.items():
                counts[k] = counts.get(k, 0) + n

        by_name = {scene.name: scene for _, scene in scenes}
        out = StudyResults(artefacts=Artefacts(self.cache.root), reference=self._reference_of(scenes),
                           display=lambda name, t, w, h: self.display(by_name[name], t, w, h),
                           thesis_history=self.profile.thesis_history, tolerances=self.precision.tolerances)
        out.precision = {}
        every = {(t.scene, t.protocol.name): set(t.reference_tasks) for t in statics + ghosts + sweeps}
        for (name, proto), seen in sorted(tried.items()):
            bounds = self.bounds_of(name, proto, every.get((name, proto)) or [None])
            out.precision.setdefault(name, {})[proto] = {"bound_lsb": min(bounds), "rule": self.precision.rule,
                                                         "bounds": {f"{b:g}": n for b, n in sorted(bounds.items())},
                                                         "over": over.get((name, proto), []), "rounds": seen}
        out.stats = {**computed_counts(results), "tasks": counts, "task_seconds": dict(session.task_seconds)}
        out.stats["runs_cached"] = max(0, sum(len(t.configs) for t in statics + ghosts + sweeps + sharpens)
                                       - out.stats["runs_computed"])
        costs = self._costs(scenes, statics, results)
        for spec, scene in scenes:
            w, h = self.resolution(scene)
            ref, cached = self.cache.get(scene, 0, w, h, **self.settings_for(scene.name))
            out.references[scene.name] = ref
            out.stats["references_rendered"] += not cached   # a damaged file found only now, re-made
            if scene.name in plan.agreements:
                out.agreements[scene.name] = results[plan.agreements[scene.name]]["data"]
        for t in statics:
            full = self._with_drift(self._result(t, results, costs))
            out.statics.append(full)
            for label, n in self.profile.static_views.items():
                out.views.setdefault(label, []).append(view(full, label, n))
        for t in ghosts:
            out.ghosts.setdefault(t.protocol.name, []).append(self._with_drift(self._result(t, results, costs)))
        out.sweeps = [self._with_drift(self._result(t, results, costs)) for t in sweeps]
        out.sharpen_sweeps = [self._result(t, results, {}) for t in sharpens]
        return out

    def _with_drift(self, res: TestResult) -> TestResult:
        """A figure's stated uncertainty: its halves' plus its change from the coarser bound."""
        change = self.drifts.get((res.scene, res.test), {})
        if not change:
            return res
        res.uncertainty = {label: {f: {m: u + change.get((res.test, label, f, m), 0.0) if u is not None else None
                                       for m, u in us.items()} for f, us in per.items()}
                           for label, per in res.uncertainty.items()}
        res.temporal_u = {label: u + change.get((res.test, label, None, "temporal"), 0.0) if u is not None else None
                          for label, u in res.temporal_u.items()}
        return res

    def _records(self, test):
        from study.engine.store import Store
        store = Store(self.cache.root)
        return {c.label: store.done(Path(test.run_folders[c.label]), test.run_keys[c.label]) for c in test.configs}

    def _result(self, test, results: dict, costs: dict) -> TestResult:
        recs = self._records(test)
        res = TestResult(test.scene, test.protocol.name, [], {}, {}, width=test.width, height=test.height,
                         kind=test.protocol.kind, reference_bound_lsb=test.ref_settings.get("se_bound_lsb", SE_BOUND_LSB),
                         reference_bounds_lsb={t: s.get("se_bound_lsb", SE_BOUND_LSB) for t, s in test.ref_settings_at.items()},
                         reference_keys={t: k for t, k in test.reference_tasks.items()})
        frames = set()
        for c in test.configs:
            m = results[test.metrics_keys[c.label]]
            if m["computed"]:
                res.recomputed.append(c.label)
            per = {int(f): v for f, v in m["data"]["per_frame"].items()}
            res.per_frame[c.label] = per
            res.uncertainty[c.label] = {int(f): v for f, v in m["data"]["uncertainty"].items()}
            res.temporal_u[c.label] = m["data"].get("temporal_u")
            frames |= set(per)
            t = m["data"].get("temporal")
            res.temporal[c.label] = math.nan if t is None else t
            rec = recs[c.label] or {}
            if rec.get("stats"):
                res.stats[c.label] = {int(f): v for f, v in rec["stats"].items()}
            cost = costs.get((test.scene, c.label), {})
            res.costs[c.label] = cost
            res.ms[c.label] = cost.get("total_ms", math.nan)
            res.artefacts[c.label] = {"folder": test.run_folders[c.label], "run_key": test.run_keys[c.label],
                                      "metrics_key": test.metrics_keys[c.label],
                                      "metrics_folder": test.metrics_folders[c.label],
                                      "output_space": (rec or {}).get("output_space", "linear"),
                                      "technique": c.name, "overrides": list(c.overrides),
                                      "maps_for": test.maps_for[c.label]}
        for label, vkey in test.video_keys.items():
            if vkey in results:
                res.jod[label] = {k: v for k, v in results[vkey]["data"]["jod"].items()}
                res.jod_u[label] = dict(results[vkey]["data"]["jod_u"])
                res.video = {k: results[vkey]["data"][k] for k in ("metric", "display", "fps")}
                res.artefacts[label]["video_key"] = vkey
                res.artefacts[label]["video_folder"] = str(self.cache.root / "video" / test.scene / vkey)
        res.frames = sorted(frames)
        if test.protocol.kind == "static":
            res.checkpoints = res.per_frame
        return res

    # -- costs: serial, after everything else ---------------------------------------------------------
    def _costs(self, scenes, statics, results) -> dict:
        from study.engine import costs as C
        return C.measure_study(self.cache.root, scenes, statics, self._records, self.display, self.progress)


__all__ = ["Study", "StudyResults", "StudyStopped", "TestResult", "is_animated"]


def _seeded_early(tests, seeded: set, ghost: set) -> frozenset:
    """The tests whose agreement and video a seeded study plans in its first round: each started at
    an earlier study's bound, with every ghosting protocol of its scene (they share references)."""
    unseeded = {s for s, p in tests if p in ghost and (s, p) not in seeded}
    return frozenset(k for k in tests if k in seeded and not (k[1] in ghost and k[0] in unseeded))
