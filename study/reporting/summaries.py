"""The study's summary tables, across scenes and protocols: the headline, the reproduction of the
thesis's results, speed against error, history convergence, the references' convergence and
sparse supersampling's cost. A mixin of study.reporting.report.Report (its _table and _file)."""
from __future__ import annotations

import math

import numpy as np

import backend
from study.reporting import plots
from study.reporting.tables import Table, best_of, fmt, fmt_u
from study.reporting.thesis import (THESIS_COLUMNS, THESIS_GHOST_FRAMES, THESIS_GHOST_MSE, THESIS_SHARPEN,
                                    THESIS_STATIC_PSNR, THESIS_STATIC_SSIM)


def rank(values: dict[str, float]) -> list[str]:
    return sorted(values, key=lambda k: -values[k])


def spearman(a: list[str], b: list[str]) -> float:
    """Spearman's rho of two rankings (best first) over the labels both hold; NaN under two."""
    common = [x for x in a if x in b]
    if len(common) < 2:
        return math.nan
    # rankings have no ties, so rho is the Pearson correlation of the ranks (scipy's import, 0.5-1 s,
    # was most of a no-op report's start)
    ra, rb = (np.argsort(np.argsort([r.index(x) for x in common])) for r in (a, b))
    return float(np.corrcoef(ra, rb)[0, 1])


class Summaries:
    def headline(self, views: dict) -> None:
        """Static test, PSNR / SSIM per scene, one row per labelled protocol (view label -> results)."""
        if not views:
            return
        first = next(iter(views.values()))
        if not first:
            return
        labels = list(first[0].per_frame)
        rows = []
        for i, r0 in enumerate(first):
            for vlabel, results in views.items():
                r = results[i]
                n = r.frames[-1]
                psnr = {l: r.per_frame[l][n]["psnr"] for l in labels if l in r.per_frame}
                ssim = {l: r.per_frame[l][n]["ssim"] for l in labels if l in r.per_frame}
                us = {m: max((u for l in labels for u in [r.uncertainty.get(l, {}).get(n, {}).get(m)] if u is not None),
                             default=None) for m in ("psnr", "ssim")}
                rows.append([r.scene, vlabel] + [f"{fmt('psnr', psnr.get(l), us['psnr'])} / "
                                                  f"{fmt('ssim', ssim.get(l), us['ssim'])}" for l in labels]
                            + [best_of("psnr", psnr) or "–", f"{fmt_u(us['psnr'])} / {fmt_u(us['ssim'])}"])
        self._table("headline", Table("Static test, PSNR (dB) / SSIM on 8-bit display images",
                                      ["scene", "protocol"] + labels + ["best PSNR", "± reference"], rows,
                                      "Techniques without history (No AA, FXAA, SMAA, SSAA) give the same image "
                                      "under both protocols. ± reference: the row's largest reference uncertainty "
                                      "(study.metrics.uncertainty); each row is printed to it."),
                    {"scenes": [r.scene for r in first], "protocols": list(views)})

    def reproduction(self, views: dict, ghosts: dict) -> None:
        """The thesis's rankings against ours, per scene and labelled protocol."""
        rows = []
        for vlabel, r in [(v, r) for v, rs in views.items() for r in rs]:
            if r.scene not in THESIS_STATIC_PSNR:
                continue
            t = r.frames[-1]
            thesis = dict(zip(THESIS_COLUMNS, THESIS_STATIC_PSNR[r.scene]))
            ours = {c: r.per_frame[l][t]["psnr"] for c, l in self.roles.items() if l in r.per_frame}
            shared = [l for l in THESIS_COLUMNS if l in ours]
            t_rank = [l for l in rank(thesis) if l in shared]
            o_rank = rank(ours)
            claim_t = thesis["Improved"] > thesis["Uncharted"]
            claim_o = ours.get("Improved", -1) > ours.get("Uncharted", math.inf) if {"Improved", "Uncharted"} <= set(ours) else None
            missing = [l for l in THESIS_COLUMNS if l not in ours]
            ssim_t = dict(zip(THESIS_COLUMNS, THESIS_STATIC_SSIM[r.scene]))
            vol = {c: r.per_frame[l][t].get("ssim_volume") for c, l in self.roles.items() if l in r.per_frame}
            ssim_cell = (f"{ssim_t['Improved'] - ssim_t['Uncharted']:+.3f} / "
                         + (f"{vol['Improved'] - vol['Uncharted']:+.3f}"
                            if vol.get("Improved") is not None and vol.get("Uncharted") is not None else "–"))
            rows.append([f"{r.scene} ({vlabel})", " > ".join(rank(thesis)), " > ".join(o_rank),
                         f"{thesis['Improved'] - thesis['Uncharted']:+.2f}",
                         "–" if claim_o is None else f"{ours['Improved'] - ours['Uncharted']:+.2f}",
                         f"{spearman(t_rank, o_rank):.2f}",
                         "–" if claim_o is None else ("yes" if claim_o == claim_t else "no"), ssim_cell,
                         ("missing: " + ", ".join(missing)) if missing else ""])
        for g in [g for gs in ghosts.values() for g in gs]:
            li, lu = self.roles.get("Improved"), self.roles.get("Uncharted")
            if g.scene not in THESIS_GHOST_MSE or not {li, lu} <= set(g.per_frame):
                continue
            tu, ti = THESIS_GHOST_MSE[g.scene]
            mu = float(np.mean([g.per_frame[lu][t]["mse"] for t in g.frames]))
            mi = float(np.mean([g.per_frame[li][t]["mse"] for t in g.frames]))
            rows.append([f"{g.scene} ({g.test}, mean MSE)", f"Improved {ti:.1f} < Uncharted {tu:.1f}",
                         f"Improved {mi:.1f} {'<' if mi < mu else '>='} Uncharted {mu:.1f}",
                         f"{ti - tu:+.1f} (MSE)", f"{mi - mu:+.1f} (MSE)", "–", "yes" if mi < mu else "no", "",
                         f"{len(g.frames)} frames (thesis: {THESIS_GHOST_FRAMES})"])
        header = ["test", "thesis ranking (PSNR)", "our ranking (PSNR)", "thesis Improved − Uncharted",
                  "ours Improved − Uncharted", "rank correlation ρ", "main claim holds",
                  "SSIM Improved − Uncharted, thesis / ours (MATLAB volume SSIM)", "note"]
        # nine columns of text (rankings): wrapped to the page's width, not shrunk to half of it
        widths = [0.13, 0.14, 0.14, 0.085, 0.085, 0.06, 0.055, 0.09, 0.09]
        self._table("reproduction", Table("Reproduction of the thesis's results (its static and ghosting figures beside ours)", header, rows,
                                          "Main claim: the improved TAA beats the Uncharted 4 / INSIDE TAA. Columns are the techniques "
                                          "that are the thesis's (registry name, default parameters): "
                                          + ", ".join(f"{c} = {l!r}" for c, l in self.roles.items())
                                          + ". The thesis computed SSIM with MATLAB's ssim on RGB volumes; "
                                          "ours in that form is compared with it.", widths=widths),
                    {"rows": [r[0] for r in rows]})

    def sharpen_test(self, views: dict, variants: dict) -> None:
        """The thesis's Table 5.1: each TAA with Xu's kernel, the normalised one and none (PSNR),
        per thesis scene and protocol, under the thesis's own four figures (its scene not named)."""
        from study.reporting.findings import KERNELS, OWN_KERNEL
        cols = [(taa, k) for taa in OWN_KERNEL for k in KERNELS]
        if not all(c in variants for c in cols):
            return
        names = {"xu": "Xu", "normalised": "normalised", "none": "none"}
        t = dict(zip(THESIS_SHARPEN["rows"], THESIS_SHARPEN["psnr"]))
        t_of = {"xu": "not normalised", "normalised": "normalised"}
        rows = [["thesis (scene not named)", "1600x900, 16 frames"]
                + [f"{t[f'{taa}, {t_of[k]}']:.2f}" if k in t_of else "–" for taa, k in cols] + ["–"]]
        for vlabel, results in views.items():
            for r in results:
                if r.scene not in THESIS_STATIC_PSNR:
                    continue
                n = r.frames[-1]
                vals = [r.per_frame.get(variants[c], {}).get(n, {}).get("psnr") for c in cols]
                us = [r.uncertainty.get(variants[c], {}).get(n, {}).get("psnr") for c in cols]
                u = max((x for x in us if x is not None), default=None)
                rows.append([r.scene, vlabel] + [fmt("psnr", v, u) for v in vals] + [fmt_u(u)])
        header = ["scene", "protocol"] + [f"{taa}, {names[k]}" for taa, k in cols] + ["± reference"]
        self._table("sharpen_test", Table(
            "The sharpen test (the thesis's Table 5.1): PSNR (dB) of each TAA with each output sharpen", header, rows,
            "Xu's kernel [[0,-1,0],[-1,5,-1],[0,-1,0]] is Uncharted's own, the normalised one "
            "[[0,-1/4,0],[-1/4,2,-1/4],[0,-1/4,0]] the improved TAA's; none shows the plain blend. The "
            "sharpen applies to the displayed output only; the history is the unsharpened blend. "
            "The thesis's row is its Table 5.1 (one scene, not named)."),
            {"rows": [r[:2] for r in rows], "variants": sorted(variants.values())})

    def ground_truth(self, views: dict, alt: dict, label: str | None) -> None:
        """The thesis's columns ranked against our path-traced reference and against the thesis's
        ground truth (a 128-sample accumulation of our raster; study.reporting.ground_truth)."""
        rows = []
        for vlabel, r in [(v, r) for v, rs in views.items() for r in rs]:
            per = alt.get(f"{r.scene}|{vlabel}")
            if r.scene not in THESIS_STATIC_PSNR or not per:
                continue
            n = r.frames[-1]
            thesis = dict(zip(THESIS_COLUMNS, THESIS_STATIC_PSNR[r.scene]))
            pt = {c: r.per_frame[l][n]["psnr"] for c, l in self.roles.items() if l in r.per_frame}
            acc = {c: per[l] for c, l in self.roles.items() if l in per}
            shared = [c for c in THESIS_COLUMNS if c in pt and c in acc]
            rt, rp, ra = ([c for c in rank(d) if c in shared] for d in (thesis, pt, acc))
            shift = float(np.mean([acc[c] - pt[c] for c in shared if math.isfinite(acc[c] - pt[c])] or [math.nan]))
            rows.append([r.scene, vlabel, " > ".join(rt), " > ".join(rp), " > ".join(ra),
                         f"{spearman(rp, ra):.2f}", f"{spearman(rt, rp):.2f}", f"{spearman(rt, ra):.2f}",
                         f"{shift:+.2f}", fmt("psnr", r.per_frame[label][n]["psnr"])])
        if not rows:
            return
        self._table("ground_truth", Table(
            "Ground truth: the thesis's columns ranked against our path-traced reference and against the thesis's "
            "own kind of ground truth (PSNR)",
            ["scene", "protocol", "thesis ranking", "ours, path-traced reference", "ours, 128-sample accumulation",
             "ρ path-traced / accumulation", "ρ thesis / path-traced", "ρ thesis / accumulation",
             "mean PSNR shift (dB)", f"{label} vs path-traced (dB)"], rows,
            f"The accumulation is {label!r}: 128 Halton-jittered sub-frames of our raster, the thesis's ground truth; "
            "every technique's 8-bit display image is judged against its display image under the same transform. "
            "Mean PSNR shift: against the accumulation minus against the path-traced reference, over the columns.",
            widths=[0.09, 0.09, 0.15, 0.15, 0.15, 0.07, 0.07, 0.07, 0.07, 0.07]),
            {"rows": [r[:2] for r in rows], "alt": alt})

    def speed_error(self, statics) -> None:
        """Cost per output frame (samples shaded x raster time + resolve) against error."""
        rows = []
        for r in statics:
            n = r.frames[-1]
            pts = {l: (r.ms[l], r.per_frame[l][n]["flip_ldr"]) for l in r.per_frame}
            front = plots.pareto(pts)
            for l, (ms, err) in pts.items():
                c = r.costs.get(l, {})
                rows.append([r.scene, l, f"{c.get('samples_per_pixel', math.nan):.2f}", fmt("ms", c.get("raster_ms")),
                             fmt("ms", c.get("resolve_ms")), fmt("ms", ms), fmt("psnr", r.per_frame[l][n]["psnr"]),
                             fmt("flip_ldr", err), "yes" if l in front else ""])
        self._table("speed_error", Table(
            "Speed against error (static test, converged protocol): cost per output frame on this machine",
            ["scene", "technique", "samples / pixel", "raster ms / sample", "resolve ms", "total ms / frame",
             "PSNR (dB)", "FLIP LDR", "Pareto front"], rows,
            "total = samples per pixel x raster time of one sample per pixel (+ the extra samples' shading for "
            "sparse supersampling) + the technique's resolve; resolve alone is its own column. Timed serially, warm, "
            "Dr.Jit " + backend.VARIANT + "."), {"scenes": [r.scene for r in statics]})
        if statics:
            self._file("plots/speed_error.png", lambda: plots.speed(statics), {"scenes": [r.scene for r in statics],
                                                                               "rows": rows})

    def history_convergence(self, statics, thesis_history: int) -> None:
        """Error against history length (one long static run judged at checkpoints), and the frames
        each technique needs to come within 0.1 dB of its own converged PSNR."""
        rows, curves = [], {}
        for r in statics:
            for l, per in r.checkpoints.items():
                ns = sorted(per)
                if len(ns) < 2:
                    continue        # no history: one image
                conv = per[ns[-1]]["psnr"]
                within = [n for n in ns if all(abs(per[m]["psnr"] - conv) <= 0.1 for m in ns if m >= n)]
                th = per.get(thesis_history)
                rows.append([r.scene, l, fmt("psnr", th["psnr"]) if th else "–", fmt("psnr", conv),
                             f"{conv - th['psnr']:+.2f}" if th else "–",
                             fmt("ssim", per[ns[-1]]["ssim"]), fmt("flip_ldr", per[ns[-1]]["flip_ldr"]),
                             str(within[0]) if within else f"> {ns[-1]}"])
                curves.setdefault(r.scene, {})[l] = per
        if not rows:
            return
        self._table("history_convergence", Table(
            "TAA convergence: static test error against history length (checkpoints of one run)",
            ["scene", "technique", f"PSNR at {thesis_history} (thesis)", "PSNR converged", "gap (dB)",
             "SSIM converged", "FLIP converged", "frames to within 0.1 dB"], rows,
            "Frames to within 0.1 dB: the first checkpoint after which PSNR stays within 0.1 dB of its value at the "
            "longest history."), {"scenes": sorted(curves)})
        for scene, per_l in curves.items():
            self._file(f"plots/history_convergence_{scene}.png",
                       lambda per_l=per_l, scene=scene: plots.history(scene, per_l, thesis_history),
                       {"rows": [r for r in rows if r[0] == scene]})

    def convergence(self, refs: dict) -> None:
        """The references' own convergence: cost and per-pixel noise (scene -> Reference)."""
        rows = [[name, f"{r.seconds:.2f}", f"{r.spp_mean:.0f}", str(r.spp_max), f"{r.se_p999_lsb:.3f}",
                 f"{r.se_max_lsb:.3f}", str(r.over_bound), str(r.spp_needed) if r.over_bound else "-",
                 f"{r.noise_psnr_db:.2f}"] for name, r in refs.items()]
        if not rows:
            return
        bounds = sorted({r.bound_lsb for r in refs.values()})
        held = sum(r.over_bound for r in refs.values()) == 0
        note = (f"Bound: every pixel's display-domain standard error <= {', '.join(f'{b:g}' for b in bounds)} LSB "
                f"(8-bit); {'held at every pixel' if held else 'pixels over it hit the sample cap'}. "
                "SE in LSB of the worst channel; noise PSNR (mean over pixels) is the secondary figure. "
                "Worst would take: the samples the worst pixel over the bound would need, predicted from its "
                "SE as SE ~ 1/sqrt(spp) (an upper estimate where the sample sets stratify its detail).")
        self._table("reference_convergence", Table(
            "Reference convergence (static frame): cost and per-pixel standard error",
            ["scene", "seconds", "mean spp", "max spp", "SE p99.9 (LSB)", "SE max (LSB)", "pixels over bound",
             "worst would take (spp)", "noise PSNR (dB)"], rows, note), {n: r.key for n, r in refs.items()})
        if any(r.noise_history for r in refs.values()):
            self._file("plots/reference_convergence.png", lambda: plots.convergence(refs), {n: r.key for n, r in refs.items()})

    def sparse_cost(self, results, stem: str = "sparse_cost",
                    title: str = "Sparse supersampling: invalid pixels and extra samples shaded (means over judged frames)") -> None:
        """Techniques that shade extra samples (sparse supersampling): how many, for what quality."""
        rows = []
        for r in results:
            for label, per_t in r.stats.items():
                ts = [t for t in r.frames if t in per_t]
                if not ts:
                    continue
                inv = float(np.mean([per_t[t]["invalid_fraction"] for t in ts]))
                extra = float(np.mean([per_t[t]["samples_shaded"] for t in ts]))
                objs = float(np.mean([per_t[t]["objects_needed"] for t in ts]))
                psnr = float(np.mean([min(r.per_frame[label][t]["psnr"], 1e9) for t in ts]))
                rows.append([r.scene, r.test, label, f"{100 * inv:.2f} %", f"{extra:.0f}",
                             f"{extra / (r.width * r.height):.3f}", f"{objs:.1f} / {per_t[ts[0]]['objects_total']}",
                             fmt("psnr", psnr)])
        if rows:
            self._table(stem, Table(
                title,
                ["scene", "test", "technique", "invalid pixels", "extra samples / frame", "extra samples / pixel",
                 "objects drawn / total", "PSNR (dB)"], rows), {"scenes": sorted({r[0] for r in rows})})
