"""Chains of references that keep the previous frame's pixels (settings `reuse`, references.reuse):
where each of a test's references starts its chain (study.engine.plan plans them)."""
from __future__ import annotations


def chain_reuse(at: dict, everywhere: dict | None = None) -> dict:
    """A test's references by instant (`at`: scene time -> settings), each chain of references that
    keep the previous frame's pixels (settings `reuse`, references.reuse) confined to a run of
    consecutive instants at equal settings, or at `everywhere` (the display's, planned at every
    instant): an instant whose predecessor is neither (one the precision rule refines alone)
    starts a chain (`reuse_since`), so no reference is rendered only to be reused."""
    out, prev, run = {}, None, None
    strip = lambda d: {k: v for k, v in d.items() if k != "reuse_since"}    # noqa: E731
    for t in sorted(at):
        run = run if run is not None and t - 1 in at else t     # the first of the consecutive instants
        s = dict(at[t])
        base = strip(s)
        if s.get("reuse"):
            if everywhere is not None and base == strip(everywhere):
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
