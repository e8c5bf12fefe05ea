"""Chains of references that keep the previous frame's pixels (settings `reuse`, references.reuse):
where each of a test's references starts its chain (study.engine.plan plans them)."""
from __future__ import annotations


def chain_reuse(at: dict, whole: tuple = ()) -> dict:
    """A test's references by instant (`at`: scene time -> settings), each chain of references that
    keep the previous frame's pixels (settings `reuse`, references.reuse) confined to a run of
    consecutive instants at equal settings, or, at settings in `whole`, over the whole run of
    consecutive instants: the display's (planned at every instant) and the test's own (which its
    first round rendered at every instant), so an instant the precision rule refines alone
    changes no other instant's reference (nor its figures, study.engine.judge.FrameFigures).
    Such an instant starts a chain of its own (`reuse_since`) unless its predecessor is at its
    settings, so no finer reference is rendered only to be reused."""
    out, prev, run = {}, None, None
    strip = lambda d: {k: v for k, v in d.items() if k != "reuse_since"}    # noqa: E731
    for t in sorted(at):
        run = run if run is not None and t - 1 in at else t     # the first of the consecutive instants
        s = dict(at[t])
        base = strip(s)
        if s.get("reuse"):
            if any(base == strip(w) for w in whole):
                start = run
            else:
                start = prev[1] if prev is not None and prev[0] == t - 1 and prev[2] == base else t
            start = max(start, int(s.get("reuse_since", 0)))
            s.pop("reuse_since", None)
            if start > 0:        # from the first frame: left out, as the display's references leave it
                s["reuse_since"] = start
            prev = (t, start, base)
        else:
            prev = None
        out[t] = s
    return out
