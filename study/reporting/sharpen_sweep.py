"""The sharpen strength sweep: both thesis TAAs with the cross kernel [[0,-w,0],[-w,1+4w,-w],[0,-w,0]]
at each strength w (0 none, 0.25 the thesis's normalised kernel, 1 Xu's) on their output, judged at
the thesis's history, and the strength at which each lands on the thesis's own figure for that TAA
on that scene. A mixin of study.reporting.report.Report (the table) and the findings' factor."""
from __future__ import annotations

import numpy as np

from study.config.profile import sharpen_sweep_point
from study.reporting.tables import Table, fmt, fmt_u
from study.reporting.thesis import THESIS_COLUMNS, THESIS_STATIC_PSNR


def landings(points: list, target: float) -> list[float]:
    """The strengths w where the piecewise-linear curve through `points` [(w, PSNR), ...] (sorted
    by w) takes the value `target`."""
    out = []
    for (w0, p0), (w1, p1) in zip(points, points[1:]):
        if p0 == target:
            out.append(w0)
        elif (p0 - target) * (p1 - target) < 0:
            out.append(w0 + (target - p0) * (w1 - w0) / (p1 - p0))
    if points and points[-1][1] == target:
        out.append(points[-1][0])
    return out


def curves(sweeps) -> list[dict]:
    """Per sweep test and TAA: its (w, PSNR, ± reference) points, the thesis's figure of that TAA on
    that scene (its own kernel) and where our curve lands on it."""
    out = []
    for r in sweeps:
        n = r.frames[-1]
        by_role: dict = {}
        for label in r.per_frame:
            pt = sharpen_sweep_point(label)
            if pt is None or r.per_frame[label].get(n, {}).get("psnr") is None:
                continue
            u = (r.uncertainty.get(label, {}).get(n, {}) or {}).get("psnr") or 0.0
            by_role.setdefault(pt[0], []).append((pt[1], float(r.per_frame[label][n]["psnr"]), float(u)))
        for role, pts in sorted(by_role.items()):
            pts.sort()
            thesis = THESIS_STATIC_PSNR.get(r.scene, [None] * len(THESIS_COLUMNS))[THESIS_COLUMNS.index(role)]
            psnr = [p for _, p, _ in pts]
            out.append({"scene": r.scene, "taa": role, "resolution": f"{r.width}x{r.height}", "history": n,
                        "points": pts, "thesis": thesis,
                        "landing": landings([(w, p) for w, p, _ in pts], thesis) if thesis is not None else [],
                        "range": [min(psnr), max(psnr)], "best_w": pts[int(np.argmax(psnr))][0]})
    return out


def factor(sweeps) -> dict | None:
    """The findings' record of the sweep: per TAA, the strengths that land on the thesis's figures
    over the scenes, and on how many scenes none does."""
    cs = [c for c in curves(sweeps) if c["thesis"] is not None]
    if not cs:
        return None
    per = {}
    for role in sorted({c["taa"] for c in cs}):
        mine = [c for c in cs if c["taa"] == role]
        lands = [c["landing"][0] for c in mine if c["landing"]]
        per[role] = {"scenes": len(mine), "landed": len(lands),
                     "w": [min(lands), max(lands)] if lands else None,
                     "w_median": float(np.median(lands)) if lands else None,
                     "above_ours": sum(1 for c in mine if not c["landing"] and c["thesis"] > c["range"][1]),
                     "below_ours": sum(1 for c in mine if not c["landing"] and c["thesis"] < c["range"][0]),
                     "best_w": sorted({c["best_w"] for c in mine})}
    return {"id": "sharpen_strength", "name": "the sharpen's strength",
            "resolutions": sorted({c["resolution"] for c in cs}), "per_taa": per, "cases": cs}


def factor_sentence(f: dict) -> str:
    parts = []
    for role, p in f["per_taa"].items():
        s = f"{role}: our PSNR meets the thesis's figure on {p['landed']} of {p['scenes']} scenes"
        if p["w"]:
            s += (f", at w = {p['w'][0]:.2f}–{p['w'][1]:.2f} (median {p['w_median']:.2f}; its own kernel is "
                  f"w = {1 if role == 'Uncharted' else 0.25:g})")
        if p["above_ours"]:
            s += f"; on {p['above_ours']} the thesis's figure is above every strength's"
        if p["below_ours"]:
            s += f"; on {p['below_ours']} below every strength's"
        parts.append(s)
    return ("The sharpen's strength, swept from none (w = 0) to Xu's (w = 1) on both TAAs at the thesis's "
            f"history ({', '.join(f['resolutions'])}): " + "; ".join(parts) + ".")


class SharpenSweep:
    def sharpen_sweep(self, sweeps) -> None:
        cs = curves(sweeps)
        if not cs:
            return
        ws = sorted({w for c in cs for w, _, _ in c["points"]})
        rows = []
        for c in cs:
            at = {w: (p, u) for w, p, u in c["points"]}
            umax = max(u for _, _, u in c["points"])
            rows.append([c["scene"], c["taa"], fmt("psnr", c["thesis"]) if c["thesis"] is not None else "–"]
                        + [fmt("psnr", at[w][0], umax) if w in at else "–" for w in ws]
                        + [fmt_u(umax), ", ".join(f"{x:.2f}" for x in c["landing"]) or
                           ("none (thesis above)" if c["thesis"] is not None and c["thesis"] > c["range"][1]
                            else "none (thesis below)" if c["thesis"] is not None else "–")])
        res = ", ".join(sorted({c["resolution"] for c in cs}))
        note = ("Both thesis TAAs with the cross kernel [[0,−w,0],[−w,1+4w,−w],[0,−w,0]] on their output (the "
                "history unsharpened): w = 0 none, 0.25 the thesis's normalised kernel, 1 Xu's. Static test, "
                f"cold, at the thesis's history ({cs[0]['history']} frames), {res}. Thesis: the thesis's PSNR of "
                "that TAA on that scene (its own kernel: Xu's for Uncharted, the normalised one for Improved). "
                "Last column: the strengths at which our PSNR equals it, by linear interpolation between the "
                "strengths run; none where it lies outside our curve. The sweep's columns set no reference "
                "bound; their uncertainty is the ± column.")
        self._table("sharpen_sweep", Table("Sharpen strength sweep: PSNR (dB) against w, and where it meets the "
                                           "thesis's figure",
                                           ["scene", "TAA", "thesis"] + [f"w={w:g}" for w in ws]
                                           + ["± reference", "w on the thesis's figure"], rows, note),
                    {"scenes": sorted({c["scene"] for c in cs}), "strengths": ws})

