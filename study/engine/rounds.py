"""The precision loop's typed state (study.engine.runner.Study.run, study.engine.precision): named
records for a test, one instant of a test and one figure, a round's plan, and what a study carries
from one round to the next. Each round's step returns a new Progress; nothing is filled in place.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import NamedTuple


class TestKey(NamedTuple):
    """A test: a scene under one protocol (its static test, each ghosting protocol)."""
    scene: str
    protocol: str


class InstantKey(NamedTuple):
    """One instant (scene time) of a test, where it has a precision level of its own."""
    scene: str
    protocol: str
    t: int

    @property
    def test(self) -> TestKey:
        return TestKey(self.scene, self.protocol)


class FigureKey(NamedTuple):
    """One figure of a test: a metric of a column at a judged frame (frame None: the temporal RMS,
    a figure of every frame)."""
    protocol: str
    label: str
    frame: int | None
    metric: str


class Over(NamedTuple):
    """A figure over its tolerance: its key's fields, its uncertainty (the drift included) and the
    tolerance it exceeds."""
    protocol: str
    label: str
    frame: int | None
    metric: str
    uncertainty: float
    tolerance: float


def instant_levels(levels: dict, test: tuple) -> dict:
    """scene time -> level of the test's instants refined alone (`levels`: TestKey / InstantKey -> level)."""
    return {k.t: n for k, n in levels.items() if isinstance(k, InstantKey) and k.test == test}


@dataclass(frozen=True)
class Request:
    """What a study was asked to run (Study.run's arguments)."""
    specs: list
    configs: list
    agreement: bool = True
    sweep: tuple = ()
    ghosting: bool = True
    sharpen: tuple = ()
    seeded: bool = False


@dataclass(frozen=True)
class Round:
    """One round's plan (Study.plan's tuple, named) and, per test it judges, which scene time
    judges each (label, frame)."""
    plan: object
    scenes: list
    statics: list
    ghosts: list
    sweeps: list
    sharpens: list
    instants: dict = field(default_factory=dict)     # TestKey -> (label, frame) -> scene time

    @classmethod
    def of(cls, planned: tuple) -> "Round":
        plan, scenes, statics, ghosts, sweeps, sharpens = planned
        instants: dict = {}
        for t in statics + ghosts + sweeps:         # a sweep shares its protocol's references
            instants.setdefault(TestKey(t.scene, t.protocol.name), {}).update(
                {(label, f): time for label, ft in t.frame_times.items() for f, time in ft.items()})
        return cls(plan, scenes, statics, ghosts, sweeps, sharpens, instants)

    @property
    def judged(self) -> list:
        """The tests whose figures set the precision (a sweep's with its protocol's)."""
        return self.statics + self.ghosts + self.sweeps


@dataclass(frozen=True)
class Progress:
    """What a study carries from round to round."""
    levels: dict = field(default_factory=dict)   # TestKey / InstantKey -> precision level
    tried: dict = field(default_factory=dict)    # TestKey -> the bounds it was rendered to, in order
    over: dict = field(default_factory=dict)     # TestKey -> its figures over tolerance (precision.over_tolerance)
    drifts: dict = field(default_factory=dict)   # TestKey -> FigureKey -> drift
    before: dict = field(default_factory=dict)   # TestKey -> ({t: bound}, figures) when last judged
    final: bool = False           # this round's references are final: the round after it is none
    early: frozenset = frozenset()   # tests settled already: their agreement and video are planned now
    pruned: frozenset = frozenset()  # tests whose runs are pruned once judged (study.engine.disk)
    inputs: str | None = None     # the key of the study's inputs (precision.inputs_key)
    memo: dict | None = None      # where its decisions are recorded (precision.decisions)
    probes: dict | None = None    # TestKey -> its probe references' keys
    rounds: tuple = ()            # (task counts, results) of each round executed
    finished: bool = False


def log_judged(log, precision, judged, finer: dict, progress: Progress, rnd: Round, bounds_of) -> None:
    """One line per test judged this round: settled, or over its tolerance and refined (or at the
    finest bound: reported). `bounds_of(scene, protocol, instants)`: bound -> instants at it."""
    from study.engine.precision import bounds_text
    over, tried = progress.over, progress.tried
    for k in sorted(judged):
        every = set(rnd.instants[k].values())
        name, b = f"{k[0]} ({k[1]})", bounds_text(bounds_of(*k, every))
        nxt = ""
        if k in finer:
            to = Counter(precision.bound(n) for n in finer[k].values())
            nxt = "references again at " + bounds_text(to) + (
                f" ({len(finer[k])} of {len(every)} instants)" if len(finer[k]) < len(every) else "")
        if not over[k]:
            if k in finer:
                log(f"precision: {name}: every figure within its tolerance at the probe ({b} LSB); {nxt}, "
                    "where the figures ask for it and the drift can be measured")
            elif len(tried.get(k, ())) == 1:
                first = "probe" if b == f"{precision.start_bound_lsb:g}" else "first bound (an earlier study's)"
                log(f"precision: {name}: every figure within its tolerance at its {first} ({b} LSB): settled")
            continue
        w = over[k][0]
        log(f"precision: {name}: {len(over[k])} figures over their tolerance at {b} LSB, the worst "
            f"{w.metric} of {w.label} ({w.protocol}, {'every frame' if w.frame is None else f'frame {w.frame}'}) "
            f"+-{w.uncertainty:.3g} > {w.tolerance:.3g}; "
            + (nxt if k in finer else "the finest bound: reported"))


def seeded_early(tests, seeded: set, ghost: set) -> frozenset:
    """The tests whose agreement and video a seeded study plans in its first round: each started at
    an earlier study's bound, with every ghosting protocol of its scene (they share references)."""
    unseeded = {s for s, p in tests if p in ghost and (s, p) not in seeded}
    return frozenset(k for k in tests if k in seeded and not (k[1] in ghost and k[0] in unseeded))
