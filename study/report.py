"""Writes a study's artefacts: thesis-layout tables, the reproduction table, speed against error,
display images, SSIM/FLIP maps (PNG, white = similar for SSIM, and raw EXR), plots and a manifest.
Files are rewritten only when their content changes."""
from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

import numpy as np
from PIL import Image

from display import DisplayTransform
from references.exr import read_exr, write_exr

from .store import write_bytes_atomic, write_text_atomic
from .tables import METRIC_LABELS, Table, fmt, thesis_layout

STATIC_METRICS = ["mse", "rmsd", "psnr", "snr", "ssim", "flip_ldr", "flip_hdr", "relmse_hdr", "ms"]
GHOST_METRICS = ["mse", "psnr", "ssim", "flip_ldr"]

# Spec section 11: PSNR of No AA | FXAA | SMAA | Uncharted | Improved against 128-sample accumulation.
THESIS_COLUMNS = ("No AA", "FXAA", "SMAA", "Uncharted", "Improved")
THESIS_STATIC_PSNR = {
    "pipe": (38.782, 42.601, 47.066, 36.487, 46.162),
    "pipe_tilted": (36.059, 40.022, 43.644, 36.563, 43.876),
    "blinds": (28.306, 29.650, 32.674, 25.820, 33.064),
    "arched_window": (30.625, 32.209, 35.153, 29.295, 34.710),
    "atrium": (36.841, 38.945, 38.781, 31.824, 42.141),
    "flowers": (27.239, 29.931, 29.541, 21.226, 32.548),
    "hard_edges": (37.174, 38.426, 39.090, 33.164, 41.131),
    "hairball_unlit": (31.660, 34.888, 34.086, 28.638, 38.005),
    "hairball_lit": (17.009, 20.002, 18.848, 16.535, 24.579),
}
THESIS_GHOST_MSE = {"sphere_ghosting": (28.634, 19.501), "hairball_rotating_unlit": (81.887, 38.534),
                    "hairball_rotating_lit": (875.687, 671.202)}


def slug(label: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", label.lower()).strip("_")


def _png(img8: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(img8).save(buf, format="PNG")
    return buf.getvalue()


def _rank(values: dict[str, float]) -> list[str]:
    return sorted(values, key=lambda k: -values[k])


def _spearman(a: list[str], b: list[str]) -> float:
    common = [x for x in a if x in b]
    n = len(common)
    if n < 2:
        return math.nan
    ra = {x: i for i, x in enumerate([x for x in a if x in common])}
    rb = {x: i for i, x in enumerate([x for x in b if x in common])}
    d2 = sum((ra[x] - rb[x]) ** 2 for x in common)
    return 1 - 6 * d2 / (n * (n * n - 1))


def pareto(points: dict[str, tuple[float, float]]) -> set[str]:
    """Labels not dominated in (time lower, error lower)."""
    front = set()
    for a, (ta, ea) in points.items():
        if not any((tb <= ta and eb <= ea) and (tb < ta or eb < ea) for b, (tb, eb) in points.items() if b != a):
            front.add(a)
    return front


class Report:
    def __init__(self, out: Path, improved_label: str = "Improved", baseline_label: str = "Uncharted"):
        self.out = Path(out)
        self.improved, self.baseline = improved_label, baseline_label
        self.manifest: dict[str, dict] = {}
        self.markdown: list[str] = []

    def _file(self, rel: str, data, inputs: dict) -> None:
        path = self.out / rel
        (write_text_atomic if isinstance(data, str) else write_bytes_atomic)(path, data)
        self.manifest[rel] = inputs

    def _table(self, stem: str, table: Table, inputs: dict) -> None:
        self._file(f"tables/{stem}.md", table.markdown(), inputs)
        self._file(f"tables/{stem}.csv", table.csv(), inputs)
        self._file(f"tables/{stem}.tex", table.latex(), inputs)
        self.markdown.append(table.markdown())

    @staticmethod
    def _floor_note(agree: dict | None) -> str:
        if not agree:
            return ""
        return (f"Reference agreement (raster mean of {agree['raster_samples']} jittered frames vs reference): "
                f"{agree['agreement_psnr_db']:.1f} dB; reference noise {agree['reference_noise_psnr_db']:.1f} dB "
                f"at {agree['reference_spp']} spp")

    # -- static ------------------------------------------------------------------------------
    def static(self, res, agree: dict | None, cache_refs) -> None:
        t = res.frames[-1]
        results = {l: {**res.per_frame[l][t], "ms": res.ms[l]} for l in res.per_frame}
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "metrics": {l: a["metrics_key"] for l, a in res.artefacts.items()},
                  "reference": res.reference_keys[t]}
        note = f"{res.width}x{res.height}, 8-bit display images. " + self._floor_note(agree)
        table = thesis_layout(f"Static test: {res.scene}", results, STATIC_METRICS,
                              self.improved if self.improved in results else None, note)
        self._table(f"static_{res.scene}", table, inputs)
        ref = cache_refs(res.scene, t, res.width, res.height)
        disp = DisplayTransform.from_reference(ref.image)
        self._file(f"images/static_{res.scene}_reference.png", _png(disp.to_8bit(ref.image)),
                   {"reference": res.reference_keys[t]})
        for label, a in res.artefacts.items():
            folder = Path(a["folder"])
            _, ch = read_exr(folder / f"frame_{t:04d}.exr")
            img = np.stack([ch[c] for c in "RGB"], -1)
            img8 = (np.round(np.clip(img, 0, 1) * 255).astype(np.uint8) if a["output_space"] == "display"
                    else disp.to_8bit(img))
            key = {"run": a["run_key"], "metrics": a["metrics_key"]}
            self._file(f"images/static_{res.scene}_{slug(label)}.png", _png(img8), key)
            _, maps = read_exr(folder / f"maps_{a['metrics_key']}.exr")
            self._file(f"maps/static_{res.scene}_{slug(label)}_ssim.png",
                       _png(np.round(np.clip(maps["ssim"], 0, 1) * 255).astype(np.uint8)), key)
            self._file(f"maps/static_{res.scene}_{slug(label)}_flip.png", _png(_magma(maps["flip_ldr"])), key)
            exr_path = self.out / f"maps/static_{res.scene}_{slug(label)}.exr"
            if not exr_path.exists() or self.manifest.get(str(exr_path.relative_to(self.out))) != key:
                write_exr(exr_path, maps)
            self.manifest[str(exr_path.relative_to(self.out))] = key

    # -- ghosting ----------------------------------------------------------------------------
    def ghosting(self, res, agree: dict | None) -> None:
        labels = list(res.per_frame)
        header = ["metric", "statistic"] + labels
        rows = []
        for m in GHOST_METRICS:
            stats = {}
            for l in labels:
                series = {t: res.per_frame[l][t][m] for t in res.frames}
                finite = {t: v for t, v in series.items() if v is not None and not math.isnan(v)}
                order = sorted(finite, key=lambda t: finite[t], reverse=m in ("psnr", "ssim"))
                best, worst = order[0], order[-1]
                mean = float(np.mean([min(v, 1e9) for v in finite.values()]))
                stats[l] = (finite[best], best, finite[worst], worst, mean)
            rows.append([METRIC_LABELS[m], "best (frame)"] + [f"{fmt(m, s[0])} ({s[1]})" for s in stats.values()])
            rows.append(["", "worst (frame)"] + [f"{fmt(m, s[2])} ({s[3]})" for s in stats.values()])
            rows.append(["", "mean"] + [fmt(m, s[4]) for s in stats.values()])
        rows.append([METRIC_LABELS["temporal"], "sequence"] + [fmt("temporal", res.temporal[l]) for l in labels])
        rows.append([METRIC_LABELS["ms"], "median"] + [fmt("ms", res.ms[l]) for l in labels])
        note = (f"{len(res.frames)} frames at {res.width}x{res.height}, each against its own reference. "
                + self._floor_note(agree))
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "references": list(res.reference_keys.values())}
        self._table(f"ghosting_{res.scene}", Table(f"Ghosting test: {res.scene}", header, rows, note), inputs)
        self._file(f"plots/ghosting_{res.scene}.png", _plot_series(res), inputs)

    # -- summaries ---------------------------------------------------------------------------
    def headline(self, statics) -> None:
        if not statics:
            return
        labels = list(statics[0].per_frame)
        rows = []
        for r in statics:
            t = r.frames[-1]
            psnr = {l: r.per_frame[l][t]["psnr"] for l in labels if l in r.per_frame}
            ssim = {l: r.per_frame[l][t]["ssim"] for l in labels if l in r.per_frame}
            rows.append([r.scene] + [f"{fmt('psnr', psnr.get(l))} / {fmt('ssim', ssim.get(l))}" for l in labels]
                        + [max(psnr, key=psnr.get)])
        self._table("headline", Table("Static test, PSNR (dB) / SSIM on 8-bit display images",
                                      ["scene"] + labels + ["best PSNR"], rows), {"scenes": [r.scene for r in statics]})

    def reproduction(self, statics, ghosts) -> None:
        rows = []
        for r in statics:
            if r.scene not in THESIS_STATIC_PSNR:
                continue
            t = r.frames[-1]
            thesis = dict(zip(THESIS_COLUMNS, THESIS_STATIC_PSNR[r.scene]))
            ours = {l: r.per_frame[l][t]["psnr"] for l in THESIS_COLUMNS if l in r.per_frame}
            shared = [l for l in THESIS_COLUMNS if l in ours]
            t_rank = [l for l in _rank(thesis) if l in shared]
            o_rank = _rank(ours)
            claim_t = thesis["Improved"] > thesis["Uncharted"]
            claim_o = ours.get("Improved", -1) > ours.get("Uncharted", math.inf) if {"Improved", "Uncharted"} <= set(ours) else None
            missing = [l for l in THESIS_COLUMNS if l not in ours]
            rows.append([r.scene, " > ".join(_rank(thesis)), " > ".join(o_rank),
                         f"{thesis['Improved'] - thesis['Uncharted']:+.2f}",
                         "–" if claim_o is None else f"{ours['Improved'] - ours['Uncharted']:+.2f}",
                         f"{_spearman(t_rank, o_rank):.2f}",
                         "–" if claim_o is None else ("yes" if claim_o == claim_t else "no"),
                         ("missing: " + ", ".join(missing)) if missing else ""])
        for g in ghosts:
            if g.scene not in THESIS_GHOST_MSE or not {"Improved", "Uncharted"} <= set(g.per_frame):
                continue
            tu, ti = THESIS_GHOST_MSE[g.scene]
            mu = float(np.mean([g.per_frame["Uncharted"][t]["mse"] for t in g.frames]))
            mi = float(np.mean([g.per_frame["Improved"][t]["mse"] for t in g.frames]))
            rows.append([f"{g.scene} (ghosting, mean MSE)", f"Improved {ti:.1f} < Uncharted {tu:.1f}",
                         f"Improved {mi:.1f} {'<' if mi < mu else '>='} Uncharted {mu:.1f}",
                         f"{ti - tu:+.1f} (MSE)", f"{mi - mu:+.1f} (MSE)", "–", "yes" if mi < mu else "no",
                         f"{len(g.frames)} frames (thesis: 100)"])
        header = ["test", "thesis ranking (PSNR)", "our ranking (PSNR)", "thesis Improved−Uncharted",
                  "ours Improved−Uncharted", "rank correlation ρ", "main claim holds", "note"]
        self._table("reproduction", Table("Reproduction of the thesis's results (spec section 11)", header, rows,
                                          "Main claim: the improved TAA beats the Uncharted 4 / INSIDE TAA."),
                    {"scenes": [r[0] for r in rows]})

    def speed_error(self, statics) -> None:
        rows = []
        for r in statics:
            t = r.frames[-1]
            pts = {l: (r.ms[l], r.per_frame[l][t]["flip_ldr"]) for l in r.per_frame}
            front = pareto(pts)
            for l, (ms, err) in pts.items():
                rows.append([r.scene, l, fmt("ms", ms), fmt("psnr", r.per_frame[l][t]["psnr"]), fmt("flip_ldr", err),
                             "yes" if l in front else ""])
        self._table("speed_error", Table("Speed against error (static test; time per frame on this machine, "
                                         "Dr.Jit LLVM backend, including NumPy conversion)",
                                         ["scene", "technique", "ms / frame", "PSNR (dB)", "FLIP LDR", "Pareto front"],
                                         rows), {"scenes": [r.scene for r in statics]})
        if statics:
            self._file("plots/speed_error.png", _plot_speed(statics), {"scenes": [r.scene for r in statics]})

    def convergence(self, refs: dict) -> None:
        """The references' own convergence: spp and seconds against their noise (scene -> Reference)."""
        rows = [[name, str(r.spp), str(r.passes), f"{r.seconds:.2f}", f"{r.noise_psnr_db:.2f}"]
                for name, r in refs.items()]
        if not rows:
            return
        self._table("reference_convergence", Table(
            "Reference convergence (static frame): samples per pixel and time to reach the noise target",
            ["scene", "spp", "passes", "seconds", "noise PSNR (dB)"], rows), {n: r.key for n, r in refs.items()})
        if any(r.noise_history for r in refs.values()):
            self._file("plots/reference_convergence.png", _plot_convergence(refs), {n: r.key for n, r in refs.items()})

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

    def finish(self, summary: dict) -> None:
        self._file("study.md", "# TAA study\n\n" + "\n".join(self.markdown), {"tables": sorted(self.manifest)})
        write_text_atomic(self.out / "manifest.json",
                          json.dumps({"summary": summary, "artefacts": self.manifest}, indent=1, sort_keys=True,
                                     default=str))


def _magma(x: np.ndarray) -> np.ndarray:
    from matplotlib import colormaps
    return (colormaps["magma"](np.clip(x, 0, 1))[..., :3] * 255).astype(np.uint8)


def _fig_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    import matplotlib.pyplot as plt
    plt.close(fig)
    return buf.getvalue()


def _plot_series(res) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for l in res.per_frame:
        ax.plot(res.frames, [min(res.per_frame[l][t]["psnr"], 99) for t in res.frames], label=l)
    ax.set_xlabel("frame")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(f"Ghosting test: {res.scene}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _fig_bytes(fig)


def _plot_convergence(refs) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for name, r in refs.items():
        h = r.noise_history
        if h:
            ax.plot([x[0] for x in h], [x[2] for x in h], label=name, lw=0.9)
    ax.set_xscale("log")
    ax.set_xlabel("samples per pixel")
    ax.set_ylabel("reference noise PSNR (dB)")
    ax.legend(fontsize=5, ncol=2)
    fig.tight_layout()
    return _fig_bytes(fig)


def _plot_speed(statics) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = list(statics[0].per_frame)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for l in labels:
        ms = [r.ms[l] for r in statics if l in r.ms]
        err = [r.per_frame[l][r.frames[-1]]["flip_ldr"] for r in statics if l in r.per_frame]
        ax.scatter([float(np.median(ms))], [float(np.mean(err))], label=l)
    med = {l: (float(np.median([r.ms[l] for r in statics])), float(np.mean([r.per_frame[l][r.frames[-1]]["flip_ldr"]
                                                                             for r in statics]))) for l in labels}
    front = sorted(pareto(med), key=lambda l: med[l][0])
    ax.plot([med[l][0] for l in front], [med[l][1] for l in front], "k--", lw=0.8, label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel("ms per frame (median over scenes)")
    ax.set_ylabel("mean FLIP (LDR)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _fig_bytes(fig)
