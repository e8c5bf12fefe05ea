"""A study's deadline (`run --stop-after`): the exception that says it stopped before it finished,
and what it had computed by then."""
from __future__ import annotations

from collections import Counter


class StudyStopped(Exception):
    """A study stopped at its deadline (`run --stop-after`) before it finished: the tasks in flight
    finished and are in the cache, the rest were not started; the same command again resumes it.
    `computed`: what this study computed before it stopped (the counts of a finished study's
    summary); `not_started`: task kind -> tasks left; `rounds`: precision rounds begun."""

    def __init__(self, computed: dict, not_started: Counter, rounds: int):
        self.computed, self.not_started, self.rounds = computed, not_started, rounds
        left = ", ".join(f"{k} {n}" for k, n in sorted(not_started.items())) or "the next round's"
        super().__init__(f"stopped at the deadline in precision round {rounds}: tasks not started {left}; "
                         f"computed before it: runs {computed['runs_computed']}, metrics "
                         f"{computed['metrics_computed']}, references {computed['references_rendered']}")


def computed_counts(results: dict) -> dict:
    """What a study's task results computed (not found in the cache): its summary's counts."""
    return {"runs_computed": sum(len([r for r in v["runs"].values() if r["computed"]])
                                 for v in results.values() if v["kind"] == "run"),
            "metrics_computed": sum(1 for v in results.values() if v["kind"] == "metrics" and v["computed"]),
            "video_computed": sum(1 for v in results.values() if v["kind"] == "video" and v["computed"]),
            "references_rendered": sum(1 for v in results.values() if v["kind"] == "reference" and v["rendered"])}


def stop(rounds: list, partial: dict, not_started: Counter):
    """Raise StudyStopped: the finished rounds' and this round's finished tasks counted."""
    results: dict = {}
    for _, r in rounds + [(None, partial)]:
        for k, v in r.items():
            results.setdefault(k, v)
    raise StudyStopped(computed_counts(results), not_started, len(rounds) + 1)
