"""Chains of references that keep the previous frame's pixels (settings `reuse`, references.reuse):
where each of a test's references starts its chain (study.engine.plan plans them)."""
from __future__ import annotations


def chain_reuse(at: dict, whole: tuple = (), bridge=None) -> dict:
    """A test's references by instant (`at`: scene time -> settings), each chain of references that
    keep the previous frame's pixels (settings `reuse`, references.reuse) confined to a run of
    consecutive instants at equal settings, or, at settings in `whole`, over the whole run of
    consecutive instants: the display's (planned at every instant) and the test's own (which its
    first round rendered at every instant), so an instant the precision rule refines alone
    changes no other instant's reference (nor its figures, study.engine.judge.FrameFigures).
    Such an instant starts a chain of its own (`reuse_since`) unless its predecessor is at its
    settings, so no finer reference is rendered only to be reused; or unless `bridge(p, t)` says
    the instants p + 1 .. t, rendered at its settings keeping their predecessors' pixels, cost
    less than t rendered whole (p: the last instant before t at its settings in the run): the
    chain then goes on from p through them (the planner plans them too), where the figures' rule
    had refined scattered instants of a ghosting test to one bound (each a whole frame)."""
    out, run, last = {}, None, {}
    strip = lambda d: {k: v for k, v in d.items() if k != "reuse_since"}    # noqa: E731
    for t in sorted(at):
        if run is None or t - 1 not in at:      # the first of the consecutive instants
            run, last = t, {}
        s = dict(at[t])
        base = strip(s)
        if s.get("reuse"):
            mine = repr(sorted(base.items()))
            if any(base == strip(w) for w in whole):
                start = run
            else:
                p = last.get(mine)
                start = p[1] if p is not None and (p[0] == t - 1 or (bridge is not None and bridge(p[0], t))) else t
            start = max(start, int(s.get("reuse_since", 0)))
            s.pop("reuse_since", None)
            if start > 0:        # from the first frame: left out, as the display's references leave it
                s["reuse_since"] = start
            last[mine] = (t, start)
        out[t] = s
    return out


_FRESH: dict = {}


def bridge_by_kept(scene, width: int, height: int, at_most: float = 0.5):
    """`chain_reuse`'s bridge for one scene at one size: whether instants p + 1 .. t, each keeping
    what references.reuse.reuse_mask lets it keep of its predecessor, trace at most `at_most` of a
    whole frame together (a frame keeping nothing counts whole). Half a frame, not one: the pixels
    a moving object crosses are usually the costly ones (its edges), so they trace more than their
    share (sphere_ghosting at 320x180 keeps 96.5 % of a frame: a gap of up to 13 instants is
    bridged; a spinning hairball keeps 34 %: none)."""
    from references.reuse import reuse_mask

    def fresh(t: int) -> float:
        memo = (scene.content_hash, t, width, height)
        if memo not in _FRESH:
            m = reuse_mask(scene, t, width, height) if t > 0 else None
            _FRESH[memo] = 1.0 if m is None else float(1.0 - m.mean())
        return _FRESH[memo]

    return lambda p, t: sum(fresh(u) for u in range(p + 1, t + 1)) <= at_most
