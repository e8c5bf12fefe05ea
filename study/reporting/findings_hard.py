"""What the study finds on today's hard cases (scenes/library/modern.py: specular shimmer, thin
glossy rails, alpha-tested foliage, texture crawl): which columns reduce flicker, and at what blur cost.

Per ghosting protocol (a cold start measures the history's convergence too; a warm one, steady
flicker) and per column, from each hard-case scene's test:
its temporal RMS (Oliveros 2018, §3.9: the RMS of the frame-to-frame differences' error against
the reference's, which flicker and crawl raise) as a ratio to No AA's, and its mean PSNR and FLIP
against the reference beside No AA's (a column that steadies the image by blurring it loses PSNR
and gains FLIP there); the baseline TAA's variants (a preset's switch on, or its own parameters
changed: its sharpen off, say) against the baseline itself too; ColorVideoVDP's JOD where the study ran it. A scene counts as steadier when
the column's temporal RMS plus its reference uncertainty is below the other's minus its own.
"""
from __future__ import annotations

import math

import numpy as np

# the baseline TAA with one anti-flicker switch on (taa_impl's presets), judged against the baseline
PRESETS = {"taa_tonemap_blend": "Karis 2014's tonemapped blend", "taa_variance": "Salvi 2016's variance clipping",
           "taa_ycocg": "a YCoCg neighbourhood box", "taa_ycocg_variance": "YCoCg, variance clipping, "
           "Catmull-Rom history and the tonemapped blend together"}


def hard_case_scenes() -> tuple:
    """The built-in scenes of today's hard cases: those scenes/library/modern.py makes."""
    from scenes.builtin import BUILTIN
    from scenes.library import modern
    return tuple(n for n, f in BUILTIN.items() if getattr(f, "__module__", None) == modern.__name__)


def _mean(g, label: str, metric: str) -> float:
    xs = [g.per_frame[label][t].get(metric) for t in g.frames]
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return float(np.mean(xs)) if xs else math.nan


def _variant(g, label: str) -> str | None:
    """What a column changes on the baseline TAA (a preset's switch, or its own parameters), None
    for a column that is no such variant."""
    a = g.artefacts.get(label, {})
    name, overrides = a.get("technique"), a.get("overrides") or []
    if name in PRESETS and not overrides:
        return f"{PRESETS[name]} on the baseline TAA"
    if name == "taa_baseline" and overrides:
        return "the baseline TAA with " + ", ".join(f"{k} = {v}" for k, v in overrides)
    return None


def _mean_u(g, label: str, metric: str) -> float:
    """The reference uncertainty of a column's mean over frames (sqrt(sum u^2) / n, the frames' own)."""
    us = [g.uncertainty.get(label, {}).get(t, {}).get(metric) for t in g.frames]
    return math.sqrt(sum(u * u for u in us if u is not None)) / len(us) if us else math.nan


def _spread(xs: list) -> dict:
    xs = [x for x in xs if math.isfinite(x)]
    return {} if not xs else {"mean": float(np.mean(xs)), "min": float(min(xs)), "max": float(max(xs)), "n": len(xs)}


def _against(g, label: str, base: str) -> dict:
    """One scene: `label` against `base` (temporal RMS ratio, PSNR and FLIP differences, steadier)."""
    t, tb = g.temporal.get(label, math.nan), g.temporal.get(base, math.nan)
    u, ub = g.temporal_u.get(label) or 0.0, g.temporal_u.get(base) or 0.0
    return {"ratio": t / tb if tb else math.nan, "psnr": _mean(g, label, "psnr") - _mean(g, base, "psnr"),
            "flip": _mean(g, label, "flip_ldr") - _mean(g, base, "flip_ldr"),
            "steadier": bool(t + u < tb - ub), "unsteadier": bool(t - u > tb + ub)}


def _summary(rows: list) -> dict:
    return {"ratio": _spread([r["ratio"] for r in rows]), "psnr": _spread([r["psnr"] for r in rows]),
            "flip": _spread([r["flip"] for r in rows]), "steadier": sum(r["steadier"] for r in rows),
            "unsteadier": sum(r["unsteadier"] for r in rows), "of": len(rows)}


def hard_cases(res, roles: dict, scenes=None) -> list[dict]:
    """The hard-case factor records (module docstring) of a study's results, one a ghosting protocol
    that tested any of those scenes with a No AA column. `scenes`: their names (default:
    hard_case_scenes())."""
    scenes = set(hard_case_scenes() if scenes is None else scenes)
    noaa = roles.get("No AA")
    out = []
    for pname, results in res.ghosts.items():
        tests = [g for g in results if g.scene in scenes and noaa in g.per_frame]
        if tests:
            out.append(_record(pname, sorted(tests, key=lambda g: g.scene), noaa, roles.get("Uncharted")))
    return out


def _record(pname: str, tests: list, noaa: str, base: str | None) -> dict:
    labels = []
    for g in tests:
        labels += [l for l in g.per_frame if l not in labels and l != noaa]
    columns = {}
    for label in labels:
        on = [g for g in tests if label in g.per_frame]
        col = {"technique": on[0].artefacts.get(label, {}).get("technique"), "scenes": [g.scene for g in on],
               "vs_no_aa": _summary([_against(g, label, noaa) for g in on]),
               "jod": _spread([g.jod.get(label, {}).get("sequence", math.nan) - g.jod.get(noaa, {}).get("sequence",
                                                                                                        math.nan)
                               for g in on])}
        variant = _variant(on[0], label)
        if variant and base and label != base:
            col["preset"] = variant
            col["vs_uncharted"] = _summary([_against(g, label, base) for g in on if base in g.per_frame])
        columns[label] = col
    mean_u = {m: max((_mean_u(g, l, m) for g in tests for l in g.per_frame), default=math.nan)
              for m in ("psnr", "flip_ldr")}
    return {"id": "hard_cases", "name": "today's hard cases", "protocol": pname, "no_aa": noaa, "uncharted": base,
            "mean_u": mean_u, "scenes": [g.scene for g in tests],
            "resolutions": sorted({f"{g.width}x{g.height}" for g in tests}), "columns": columns}


def _n(x: dict, key: str = "mean", d: int = 2, sign: bool = True) -> str:
    v = x.get(key)
    if v is None or not math.isfinite(v):
        return "–"
    return f"{v:+.{d}f}" if sign else f"{v:.{d}f}"


def _range(x: dict, d: int, sign: bool = True) -> str:
    if not x:
        return "–"
    if x["n"] == 1:
        return _n(x, d=d, sign=sign)
    return f"{_n(x, d=d, sign=sign)} ({_n(x, 'min', d, sign)} to {_n(x, 'max', d, sign)})"


def _versus(s: dict, other: str) -> str:
    how = (f"steadier than {other} on {s['steadier']} of {s['of']} scenes"
           + (f", less steady on {s['unsteadier']}" if s["unsteadier"] else ""))
    return (f"temporal RMS {_range(s['ratio'], 2, False)} times {other}'s ({how}), at {_range(s['psnr'], 2)} dB "
            f"PSNR and {_range(s['flip'], 3)} FLIP against it")


def sentences(f: dict) -> list[str]:
    """The hard-case record in words: one lead sentence, then one per column."""
    where = f"{len(f['scenes'])} scenes, {', '.join(f['resolutions'])}; {f['protocol']}"
    out = []
    order = sorted(f["columns"], key=lambda l: f["columns"][l]["vs_no_aa"]["ratio"].get("mean", math.inf))
    steadier = [l for l in order if f["columns"][l]["vs_no_aa"]["steadier"] == f["columns"][l]["vs_no_aa"]["of"]]
    out.append(f"On today's hard cases ({where}: {', '.join(f['scenes'])}), the columns steadier than No AA on every "
               f"scene, steadiest first: {', '.join(steadier) if steadier else 'none'}; a ratio below 1 is less "
               "flicker and crawl, a PSNR loss or FLIP gain against the reference the blur it costs (means over the "
               f"frames, each within ±{_n(f['mean_u'], 'psnr', 3, False)} dB PSNR and "
               f"±{_n(f['mean_u'], 'flip_ldr', 4, False)} FLIP of the reference's uncertainty).")
    for label in order:
        c = f["columns"][label]
        s = f"{label}: {_versus(c['vs_no_aa'], 'No AA')}"
        if "vs_uncharted" in c and c["vs_uncharted"]["of"]:
            s += f"; {c['preset']}: {_versus(c['vs_uncharted'], f['uncharted'])}"
        if c["jod"]:
            s += f"; JOD {_range(c['jod'], 2)} against No AA's"
        out.append(s + ".")
    return out
