"""The upscaling table: quality and cost against render scale, per scene and upscaler, beside the
techniques that render at the output's size. A mixin of study.reporting.report.Report."""
from __future__ import annotations

import math

import numpy as np

from study.config.techniques import family, render_scale, upsamples
from study.reporting.tables import Table, fmt


def scaled_columns(configs) -> dict[str, tuple[str, float]]:
    """label -> (upscaler family, render scale) of every column that upsamples."""
    out = {}
    for c in configs:
        try:
            if upsamples(c):
                out[c.label] = (family(c), render_scale(c))
        except ValueError:        # a technique that no longer resolves has no results either
            continue
    return out


def _mean_psnr(per: dict) -> float:
    vals = [min(v["psnr"], 1e9) for v in per.values() if v.get("psnr") is not None]
    return float(np.mean(vals)) if vals else math.nan


class Upscaling:
    def upscaling(self, statics, ghosts: dict, configs, native: str | None) -> None:
        """`statics`: the converged static results; `ghosts`: protocol -> results; `native`: the
        label of the output-size TAA the upscalers are measured against (the thesis's Uncharted)."""
        cols = scaled_columns(configs)
        if not cols or not statics:
            return
        ghost_by = {(p, g.scene): g for p, gs in ghosts.items() for g in gs}
        rows, keep = [], {}
        for r in statics:
            n = r.frames[-1]
            labels = [l for l in r.per_frame if l in cols]
            fams = sorted({cols[l][0] for l in labels})
            base = r.per_frame.get(native, {}).get(n) if native else None
            for fam in fams:
                at = sorted((l for l in labels if cols[l][0] == fam), key=lambda l: -cols[l][1])
                own1 = next((r.per_frame[l][n]["psnr"] for l in at if cols[l][1] == 1.0), None)
                for l in at:
                    m = r.per_frame[l][n]
                    c = r.costs.get(l, {})
                    row = [r.scene, fam, f"{cols[l][1]:g}", f"{c.get('samples_per_pixel', math.nan):.2f}",
                           fmt("ms", r.ms.get(l)), fmt("psnr", m["psnr"]), fmt("ssim", m["ssim"]),
                           fmt("flip_ldr", m["flip_ldr"]),
                           f"{m['psnr'] - own1:+.2f}" if own1 is not None else "–",
                           f"{m['psnr'] - base['psnr']:+.2f}" if base else "–"]
                    for p in ghosts:
                        g = ghost_by.get((p, r.scene))
                        row.append(fmt("psnr", _mean_psnr(g.per_frame[l])) if g and l in g.per_frame else "–")
                    rows.append(row)
                    keep.setdefault((fam, cols[l][1]), []).append(
                        (m["psnr"] - base["psnr"]) if base else math.nan)
        if not rows:
            return
        header = ["scene", "upscaler", "render scale", "samples / pixel", "ms / frame", "PSNR (dB)", "SSIM",
                  "FLIP LDR", "PSNR vs its scale 1", f"PSNR vs {native}" if native else "PSNR vs native TAA"]
        header += [f"{p} mean PSNR" for p in ghosts]
        summary = []
        for (fam, s), d in sorted(keep.items(), key=lambda kv: (kv[0][0], -kv[0][1])):
            d = [x for x in d if math.isfinite(x)]
            if d:
                summary.append(f"{fam} ×{s:g}: {np.mean(d):+.2f} dB (min {min(d):+.2f}, max {max(d):+.2f}, "
                               f"{len(d)} scenes)")
        note = ("Static test at the converged history; each upscaler renders render_scale × the output's size "
                "(samples / pixel = its share of the output's pixels) and is judged at the output's size against "
                "the same reference. ms / frame: the raster at the render size plus the technique's resolve, timed "
                "serially, warm. Ghosting columns: mean PSNR over the test's judged frames.")
        if summary and native:
            note += f" Mean PSNR against {native} at the output's size over the scenes: " + "; ".join(summary) + "."
        self._table("upscaling", Table("Upscaling: quality and cost against render scale", header, rows, note),
                    {"scenes": sorted({r[0] for r in rows}), "columns": sorted(cols)})
