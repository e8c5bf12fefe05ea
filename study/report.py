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
from references.exr import write_exr

from .plan import shown_frames
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
THESIS_STATIC_SSIM = {
    "pipe": (0.999, 0.999, 1.000, 0.996, 1.000),
    "pipe_tilted": (0.998, 0.999, 1.000, 0.996, 0.999),
    "blinds": (0.986, 0.990, 0.995, 0.976, 0.995),
    "arched_window": (0.992, 0.994, 0.997, 0.989, 0.996),
    "atrium": (0.988, 0.991, 0.991, 0.938, 0.991),
    "flowers": (0.959, 0.975, 0.972, 0.863, 0.985),
    "hard_edges": (0.997, 0.997, 0.998, 0.989, 0.998),
    "hairball_unlit": (0.962, 0.978, 0.974, 0.934, 0.985),
    "hairball_lit": (0.801, 0.865, 0.841, 0.785, 0.937),
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
    """Artefacts of one study in `out`. Every file is listed in manifest.json with the keys of its
    inputs and its SHA-256; a file whose inputs and content are unchanged is not made again, and
    `finish` removes every file of out/{tables,images,maps,plots} that this study did not write."""

    FOLDERS = ("tables", "images", "maps", "plots")

    def __init__(self, out: Path, store=None, roles: dict | None = None):
        """`roles`: thesis column (THESIS_COLUMNS) -> the label of the technique that *is* it (registry
        name with default parameters; study.config.thesis_roles), whatever the study calls it."""
        self.out = Path(out)
        self.store = store
        self.roles = dict(roles) if roles is not None else {c: c for c in THESIS_COLUMNS}
        self.improved = self.roles.get("Improved")
        self.manifest: dict[str, dict] = {}
        self.markdown: list[str] = []
        try:
            self.previous = json.loads((self.out / "manifest.json").read_text()).get("artefacts", {})
        except (OSError, ValueError):
            self.previous = {}

    def _unchanged(self, rel: str, inputs: dict) -> bool:
        prev = self.previous.get(rel)
        path = self.out / rel
        if not (isinstance(prev, dict) and prev.get("inputs") == json.loads(json.dumps(inputs, default=str))
                and path.exists()):
            return False
        from .store import sha256_file
        return sha256_file(path) == prev.get("sha256")

    def _file(self, rel: str, data, inputs: dict) -> None:
        """Write `data` (str, bytes, or a function making them) unless inputs and file are unchanged."""
        path = self.out / rel
        if callable(data):
            if self._unchanged(rel, inputs):
                self.manifest[rel] = self.previous[rel]
                return
            data = data()
        (write_text_atomic if isinstance(data, str) else write_bytes_atomic)(path, data)
        import hashlib
        raw = data.encode() if isinstance(data, str) else data
        self.manifest[rel] = {"inputs": json.loads(json.dumps(inputs, default=str)),
                              "sha256": hashlib.sha256(raw).hexdigest()}

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
    def static(self, res, agree: dict | None, ref, stem: str) -> None:
        """One static protocol's table, display images and maps (res: a view of the static run)."""
        n = res.frames[-1]
        results = {l: {**res.per_frame[l][n], "ms": res.ms[l]} for l in res.per_frame}
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "metrics": {l: a["metrics_key"] for l, a in res.artefacts.items()},
                  "costs": {l: c.get("key") for l, c in res.costs.items()}}
        note = (f"{res.test}: {res.width}x{res.height}, 8-bit display images; ms / frame = raster of the samples "
                f"shaded + resolve (study.costs). " + self._floor_note(agree))
        table = thesis_layout(f"Static test, {res.test}: {res.scene}", results, STATIC_METRICS,
                              self.improved if self.improved in results else None, note)
        self._table(f"{stem}_{res.scene}", table, inputs)
        disp = DisplayTransform.from_reference(ref.image)
        self._file(f"images/{stem}_{res.scene}_reference.png", lambda: _png(disp.to_8bit(ref.image)),
                   {"reference": ref.key})
        for label, a in res.artefacts.items():
            f = a["frame"]
            key = {"run": a["run_key"], "metrics": a["metrics_key"], "frame": f}
            base = f"{stem}_{res.scene}_{slug(label)}"

            def image(a=a, f=f):
                img = self._run_image(a, f)
                return _png(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8) if a["output_space"] == "display"
                            else disp.to_8bit(img))
            self._file(f"images/{base}.png", image, key)
            if f not in a["maps_for"]:
                continue
            maps = {}

            def get_maps(a=a, f=f):
                if not maps:
                    maps.update(self._maps(a, f))
                return maps
            self._file(f"maps/{base}_ssim.png",
                       lambda: _png(np.round(np.clip(get_maps()["ssim"], 0, 1) * 255).astype(np.uint8)), key)
            self._file(f"maps/{base}_flip.png", lambda: _png(_magma(get_maps()["flip_ldr"])), key)
            self._file(f"maps/{base}.exr", lambda: _exr_bytes(get_maps()), key)

    def _run_image(self, a: dict, f: int) -> np.ndarray:
        folder = Path(a["folder"])
        rec = self.store.done(folder, a["run_key"])
        if rec is None:
            raise RuntimeError(f"run {folder} is not complete")
        ch = self.store.read_image(folder, f"frame_{f:04d}.exr", rec)
        return np.stack([ch[c] for c in "RGB"], -1)

    def _maps(self, a: dict, f: int) -> dict:
        folder = Path(a["metrics_folder"])
        rec = self.store.done(folder, a["metrics_key"])
        if rec is None:
            raise RuntimeError(f"metrics {folder} are not complete")
        return self.store.read_image(folder, f"maps_{f:04d}.exr", rec)

    # -- ghosting ----------------------------------------------------------------------------
    def ghosting(self, res, agree: dict | None, stem: str = "ghosting") -> None:
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
        note = (f"{res.test}: {len(res.frames)} frames at {res.width}x{res.height}, each against its own reference. "
                + self._floor_note(agree))
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "references": list(res.reference_keys.values())}
        self._table(f"{stem}_{res.scene}", Table(f"Ghosting test, {res.test}: {res.scene}", header, rows, note), inputs)
        self._file(f"plots/{stem}_{res.scene}.png", lambda: _plot_series(res), inputs)

    def ghosting_frames(self, res, reference, max_frames: int = 24) -> dict:
        """Display images of a ghosting sequence for the HTML report's frame slider (at most
        `max_frames`, evenly spaced), and its per-frame metrics. `reference(t)` gives frame t's
        Reference. Returns the html_report 'ghosting' entry of this protocol."""
        frames = shown_frames(res.frames, max_frames)     # the frames its runs keep (study.plan)
        stem = f"ghosting_frames/{res.test}_{res.scene}"
        entry = {"frames": frames, "reference": [], "techniques": {}}
        cache: dict = {}

        def ref_of(t):
            if t not in cache:
                r = reference(t)
                cache[t] = (r, DisplayTransform.from_reference(r.image))
            return cache[t]
        for t in frames:
            rel = f"images/{stem}_reference_{t:04d}.png"
            key = {"reference": res.reference_keys.get(t)}
            self._file(rel, lambda t=t: _png(ref_of(t)[1].to_8bit(ref_of(t)[0].image)), key)
            entry["reference"].append(rel)
        for label, a in res.artefacts.items():
            imgs = []
            for t in frames:
                rel = f"images/{stem}_{slug(label)}_{t:04d}.png"

                def image(a=a, t=t):
                    img = self._run_image(a, t)
                    return _png(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8) if a["output_space"] == "display"
                                else ref_of(t)[1].to_8bit(img))
                self._file(rel, image, {"run": a["run_key"], "frame": t, "reference": res.reference_keys.get(t)})
                imgs.append(rel)
            entry["techniques"][label] = {
                "images": imgs,
                "metrics": {m: [res.per_frame[label][t].get(m) for t in frames] for m in GHOST_METRICS}}
        return entry

    # -- summaries ---------------------------------------------------------------------------
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
                rows.append([r.scene, vlabel] + [f"{fmt('psnr', psnr.get(l))} / {fmt('ssim', ssim.get(l))}"
                                                  for l in labels] + [max(psnr, key=psnr.get)])
        self._table("headline", Table("Static test, PSNR (dB) / SSIM on 8-bit display images",
                                      ["scene", "protocol"] + labels + ["best PSNR"], rows,
                                      "Techniques without history (No AA, FXAA, SMAA, SSAA) give the same image "
                                      "under both protocols."),
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
            t_rank = [l for l in _rank(thesis) if l in shared]
            o_rank = _rank(ours)
            claim_t = thesis["Improved"] > thesis["Uncharted"]
            claim_o = ours.get("Improved", -1) > ours.get("Uncharted", math.inf) if {"Improved", "Uncharted"} <= set(ours) else None
            missing = [l for l in THESIS_COLUMNS if l not in ours]
            ssim_t = dict(zip(THESIS_COLUMNS, THESIS_STATIC_SSIM[r.scene]))
            vol = {c: r.per_frame[l][t].get("ssim_volume") for c, l in self.roles.items() if l in r.per_frame}
            ssim_cell = (f"{ssim_t['Improved'] - ssim_t['Uncharted']:+.3f} / "
                         + (f"{vol['Improved'] - vol['Uncharted']:+.3f}"
                            if vol.get("Improved") is not None and vol.get("Uncharted") is not None else "–"))
            rows.append([f"{r.scene} ({vlabel})", " > ".join(_rank(thesis)), " > ".join(o_rank),
                         f"{thesis['Improved'] - thesis['Uncharted']:+.2f}",
                         "–" if claim_o is None else f"{ours['Improved'] - ours['Uncharted']:+.2f}",
                         f"{_spearman(t_rank, o_rank):.2f}",
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
                         f"{len(g.frames)} frames (thesis: 100)"])
        header = ["test", "thesis ranking (PSNR)", "our ranking (PSNR)", "thesis Improved − Uncharted",
                  "ours Improved − Uncharted", "rank correlation ρ", "main claim holds",
                  "SSIM Improved − Uncharted, thesis / ours (MATLAB volume SSIM)", "note"]
        # nine columns of text (rankings): wrapped to the page's width, not shrunk to half of it
        widths = [0.13, 0.14, 0.14, 0.085, 0.085, 0.06, 0.055, 0.09, 0.09]
        self._table("reproduction", Table("Reproduction of the thesis's results (spec section 11)", header, rows,
                                          "Main claim: the improved TAA beats the Uncharted 4 / INSIDE TAA. Columns are the techniques "
                                          "that are the thesis's (registry name, default parameters): "
                                          + ", ".join(f"{c} = {l!r}" for c, l in self.roles.items())
                                          + ". The thesis computed SSIM with MATLAB's ssim on RGB volumes; "
                                          "ours in that form is compared with it.", widths=widths),
                    {"rows": [r[0] for r in rows]})

    def speed_error(self, statics) -> None:
        """Cost per output frame (samples shaded x raster time + resolve) against error."""
        rows = []
        for r in statics:
            n = r.frames[-1]
            pts = {l: (r.ms[l], r.per_frame[l][n]["flip_ldr"]) for l in r.per_frame}
            front = pareto(pts)
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
            "Dr.Jit " + _variant() + "."), {"scenes": [r.scene for r in statics]})
        if statics:
            self._file("plots/speed_error.png", lambda: _plot_speed(statics), {"scenes": [r.scene for r in statics],
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
            f"TAA convergence: static test error against history length (checkpoints of one run)",
            ["scene", "technique", f"PSNR at {thesis_history} (thesis)", "PSNR converged", "gap (dB)",
             "SSIM converged", "FLIP converged", "frames to within 0.1 dB"], rows,
            "Frames to within 0.1 dB: the first checkpoint after which PSNR stays within 0.1 dB of its value at the "
            "longest history."), {"scenes": sorted(curves)})
        for scene, per_l in curves.items():
            self._file(f"plots/history_convergence_{scene}.png",
                       lambda per_l=per_l, scene=scene: _plot_history(scene, per_l, thesis_history),
                       {"rows": [r for r in rows if r[0] == scene]})

    def convergence(self, refs: dict) -> None:
        """The references' own convergence: cost and per-pixel noise (scene -> Reference)."""
        rows = [[name, f"{r.seconds:.2f}", f"{r.spp_mean:.0f}", str(r.spp_max), f"{r.se_p999_lsb:.3f}",
                 f"{r.se_max_lsb:.3f}", str(r.over_bound), f"{r.noise_psnr_db:.2f}"] for name, r in refs.items()]
        if not rows:
            return
        bounds = sorted({r.bound_lsb for r in refs.values()})
        held = sum(r.over_bound for r in refs.values()) == 0
        note = (f"Bound: every pixel's display-domain standard error <= {', '.join(f'{b:g}' for b in bounds)} LSB "
                f"(8-bit); {'held at every pixel' if held else 'pixels over it hit the sample cap'}. "
                "SE in LSB of the worst channel; noise PSNR (mean over pixels) is the secondary figure.")
        self._table("reference_convergence", Table(
            "Reference convergence (static frame): cost and per-pixel standard error",
            ["scene", "seconds", "mean spp", "max spp", "SE p99.9 (LSB)", "SE max (LSB)", "pixels over bound",
             "noise PSNR (dB)"], rows, note), {n: r.key for n, r in refs.items()})
        if any(r.noise_history for r in refs.values()):
            self._file("plots/reference_convergence.png", lambda: _plot_convergence(refs), {n: r.key for n, r in refs.items()})

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
        removed = 0
        for folder in self.FOLDERS:
            for path in sorted((self.out / folder).rglob("*")) if (self.out / folder).exists() else []:
                if path.is_file() and str(path.relative_to(self.out)) not in self.manifest:
                    path.unlink()       # another study's (or an older run's) file: not this study's
                    removed += 1
        summary = {**summary, "stale_files_removed": removed}
        write_text_atomic(self.out / "manifest.json",
                          json.dumps({"summary": summary, "artefacts": self.manifest}, indent=1, sort_keys=True,
                                     default=str))


def _variant() -> str:
    import backend
    return backend.VARIANT


def _plot_history(scene: str, per_label: dict, thesis_history: int) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.4))
    for l, per in per_label.items():
        ns = sorted(per)
        ax.plot(ns, [min(per[n]["psnr"], 99) for n in ns], marker=".", lw=0.9, label=l)
    ax.axvline(thesis_history, color="k", ls=":", lw=0.8, label=f"thesis ({thesis_history})")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("frames of history")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(f"TAA convergence: {scene}")
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return _fig_bytes(fig)


def _exr_bytes(channels: dict) -> bytes:
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "maps.exr"
        write_exr(path, channels)
        return path.read_bytes()


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
    """Median total cost against mean FLIP, one marker per technique, labelled beside it; the legend
    sits outside the axes so it covers no point."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = list(statics[0].per_frame)
    med = {l: (float(np.median([r.ms[l] for r in statics])),
               float(np.mean([r.per_frame[l][r.frames[-1]]["flip_ldr"] for r in statics]))) for l in labels}
    fig, ax = plt.subplots(figsize=(8, 4))
    markers = "osD^vP*Xh<>p"
    for i, l in enumerate(labels):
        x, y = med[l]
        ax.scatter([x], [y], marker=markers[i % len(markers)], s=36, label=l, zorder=3)
        ax.annotate(l, (x, y), textcoords="offset points", xytext=(5, 4 if i % 2 else -9), fontsize=6)
    front = sorted(pareto(med), key=lambda l: med[l][0])
    ax.plot([med[l][0] for l in front], [med[l][1] for l in front], "k--", lw=0.8, label="Pareto front", zorder=2)
    ax.set_xscale("log")
    ax.set_xlabel("total ms per output frame (samples shaded + resolve; median over scenes)")
    ax.set_ylabel("mean FLIP (LDR)")
    ax.margins(x=0.15, y=0.12)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    return _fig_bytes(fig)


def write_study(out: Path, study, res, configs, summary: dict, start: float) -> None:
    """Every table, image, map, plot and the interactive report of a study's results (study.run
    StudyResults) into `out`; the manifest lists exactly these files."""
    import time

    from . import html_report
    from .config import thesis_roles
    from .store import Store
    from .tasks import load_scene
    report = Report(out, Store(study.cache.root), thesis_roles(configs))
    views = res.views
    for vi, results in enumerate(views.values()):
        for r in results:
            report.static(r, res.agreements.get(r.scene), res.references[r.scene],
                          "static" if vi == 0 else "static_converged")
    for pname, results in res.ghosts.items():
        for g in results:
            report.ghosting(g, res.agreements.get(g.scene), stem=pname)
    for s in res.sweeps:
        report.sparse_cost([s], stem="sparse_sweep_" + s.scene,
                           title=f"Sparse supersampling: mu against cost and quality ({s.scene}, {s.test})")
    report.headline(views)
    report.reproduction(views, res.ghosts)
    converged = list(views.values())[-1] if views else []
    report.speed_error(converged)
    report.history_convergence(res.statics, study.profile.thesis_history)
    report.sparse_cost(converged + [g for gs in res.ghosts.values() for g in gs])
    report.convergence(res.references)
    ghost_views = {}
    specs = {load_scene(spec).name: spec for spec in summary["scenes"]}
    for pname, results in list(res.ghosts.items())[:1]:      # the first (the thesis's) ghosting protocol
        for g in results:
            scene = load_scene(specs[g.scene])
            ghost_views.setdefault(g.scene, {})[pname] = report.ghosting_frames(
                g, lambda t, scene=scene, g=g: study.reference(scene, t, g.width, g.height))
    report.finish({**summary, "seconds": round(time.perf_counter() - start, 2)})
    data = html_report.collect(out)
    for scene, gv in ghost_views.items():
        if scene in data["scenes"]:
            data["scenes"][scene]["ghosting"] = gv
    for scene, agree in res.agreements.items():
        if scene in data["scenes"]:
            data["scenes"][scene]["agreement"] = agree
    html_report.write(out, data)
