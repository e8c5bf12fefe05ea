"""A study's artefacts in its output folder: per test the thesis-layout static table, the ghosting
table, display images, SSIM/FLIP maps and plots (Report); the summary tables (study.reporting.
summaries); the manifest; and the interactive report (write_study)."""
from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from display import DisplayTransform
from provenance.files import write_bytes_atomic, write_text_atomic
from study.config.protocols import GHOSTING_FIGURES
from study.engine.results import shown_frames
from study.reporting import plots
from study.reporting.encode import magma, png, slug, strict_json
from study.reporting.findings_text import floor_note, precision_note
from study.reporting.summaries import Summaries
from study.reporting.sharpen_sweep import SharpenSweep
from study.reporting.static import Static
from study.reporting.upscaling import Upscaling
from study.metrics.uncertainty import pooled
from study.metrics.video import VERSION as VIDEO_VERSION
from study.reporting.tables import METRIC_LABELS, UNCERTAINTY_NOTE, Table, fmt, fmt_u
from study.reporting.thesis import THESIS_COLUMNS

GHOST_METRICS = list(GHOSTING_FIGURES)
# TAA_STUDY_PLOTS=0: a study writes every table, image, map and the HTML report but no matplotlib
# plot. For the test suite's tiny studies that read no plot: drawing them was about a third of
# such a study's CPU time. Unset (or any other value), every plot is made.
PLOTS_ENV = "TAA_STUDY_PLOTS"


def _state(path: Path) -> list:
    st = path.stat()
    return [st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


class Report(Summaries, Upscaling, SharpenSweep, Static):
    """Artefacts of one study in `out`. Every file is listed in manifest.json with the keys of its
    inputs and its SHA-256; a file whose inputs and content are unchanged is not made again, and
    `finish` removes the files of out/{tables,images,maps,plots} that the previous manifest listed
    and this study did not write again (a file no manifest listed is the user's and stays)."""

    FOLDERS = ("tables", "images", "maps", "plots")
    video_off = False        # the study's [video] metric is "none": its ghosting tables say so (jod_off_note)
    draw_plots = True        # False: no plots/*.png made nor listed (PLOTS_ENV; the report shows none)

    def __init__(self, out: Path, artefacts=None, roles: dict | None = None, display=None):
        """`artefacts`: the engine's reader of frames and maps (study.engine.results.Artefacts).
        `roles`: thesis column (THESIS_COLUMNS) -> the label of the technique that *is* it (registry
        name with default parameters; study.config.profile.thesis_roles), whatever the study calls it.
        `display`: (scene, t, w, h) -> the frame's display transform the figures were judged under
        (study.engine.results.StudyResults.display); by default each reference's own."""
        self.out = Path(out)
        self._display = display
        self.artefacts = artefacts
        self.roles = dict(roles) if roles is not None else {c: c for c in THESIS_COLUMNS}
        self.improved = self.roles.get("Improved")
        self.manifest: dict[str, dict] = {}
        self.markdown: list[str] = []
        self._pool, self._pending = None, []     # the images being made (_file's parallel)
        try:
            self.previous = json.loads((self.out / "manifest.json").read_text()).get("artefacts", {})
        except (OSError, ValueError):
            self.previous = {}

    def display(self, scene: str, t: int, w: int, h: int, ref) -> DisplayTransform:
        return self._display(scene, t, w, h) if self._display else DisplayTransform.from_reference(ref.image)

    def _unchanged(self, rel: str, inputs: dict) -> bool:
        """The file was made from these inputs and is as written: the same state (inode, size,
        modification and change time; any write sets the change time) or else the same hash. A
        no-op study hashed its 1558 files (0.5 s)."""
        prev = self.previous.get(rel)
        path = self.out / rel
        if not (isinstance(prev, dict) and prev.get("inputs") == json.loads(json.dumps(inputs, default=str))
                and path.exists()):
            return False
        if prev.get("state") is not None and prev["state"] == _state(path):
            return True
        from provenance.files import sha256_file
        return sha256_file(path) == prev.get("sha256")

    def _file(self, rel: str, data, inputs: dict, parallel: bool = False) -> None:
        """Write `data` (str, bytes, or a function making them) unless inputs and file are unchanged.
        `parallel`: made on a thread of the pool (an image: a frame read, display-encoded and PNG-
        encoded, mostly outside the GIL; 2900 of them were 33 s of a cold report on one core),
        written by `finish` at the latest. Never a plot (matplotlib is not thread-safe)."""
        if not self.draw_plots and rel.startswith("plots/"):
            return
        path = self.out / rel
        if callable(data):
            if self._unchanged(rel, inputs):
                self.manifest[rel] = self.previous[rel]
                return
            if parallel:
                if self._pool is None:
                    from concurrent.futures import ThreadPoolExecutor
                    import os
                    self._pool = ThreadPoolExecutor(max(1, len(os.sched_getaffinity(0))))
                self._pending.append(self._pool.submit(lambda: self._file(rel, data(), inputs)))
                return
            data = data()
        (write_text_atomic if isinstance(data, str) else write_bytes_atomic)(path, data)
        raw = data.encode() if isinstance(data, str) else data
        self.manifest[rel] = {"inputs": json.loads(json.dumps(inputs, default=str)),
                              "sha256": hashlib.sha256(raw).hexdigest(), "state": _state(path)}

    def _table(self, stem: str, table: Table, inputs: dict) -> None:
        self._file(f"tables/{stem}.md", table.markdown(), inputs)
        self._file(f"tables/{stem}.csv", table.csv(), inputs)
        self._file(f"tables/{stem}.tex", table.latex(), inputs)
        self.markdown.append(table.markdown())

    def overview(self, views: dict) -> None:
        """plots/overview.png, the report's first figure: the first static view's PSNR per scene of
        each thesis column, ours ± reference uncertainty beside the thesis's (plots.overview)."""
        from study.reporting.thesis import THESIS_STATIC_PSNR
        first = next(iter(views.values()), None) if views else None
        columns = {c: self.roles[c] for c in THESIS_COLUMNS if c in self.roles}
        if not first or not any(l in r.per_frame for r in first for l in columns.values()):
            return
        thesis = {s: dict(zip(THESIS_COLUMNS, v)) for s, v in THESIS_STATIC_PSNR.items()}
        inputs = {"figures": [[r.scene, {l: [r.per_frame[l][r.frames[-1]].get("psnr"),
                                             r.uncertainty.get(l, {}).get(r.frames[-1], {}).get("psnr")]
                                         for l in columns.values() if l in r.per_frame}] for r in first],
                  "columns": columns, "view": next(iter(views))}
        self._file("plots/overview.png", lambda: plots.overview(first, columns, thesis,
                                                                f"Static test, {next(iter(views))}"), inputs)

    # -- ghosting ----------------------------------------------------------------------------
    def ghosting(self, res, agree: dict | None, stem: str = "ghosting") -> None:
        labels = list(res.per_frame)
        header = ["metric", "statistic"] + labels + ["± reference"]
        rows = []

        def u_of(l, t, m):
            return res.uncertainty.get(l, {}).get(t, {}).get(m)

        for m in GHOST_METRICS:
            stats, us = {}, {"best": [], "worst": [], "mean": []}
            for l in labels:
                series = {t: res.per_frame[l][t][m] for t in res.frames}
                finite = {t: v for t, v in series.items() if v is not None and not math.isnan(v)}
                order = sorted(finite, key=lambda t: finite[t], reverse=m in ("psnr", "ssim"))
                best, worst = order[0], order[-1]
                mean = float(np.mean([min(v, 1e9) for v in finite.values()]))
                stats[l] = (finite[best], best, finite[worst], worst, mean)
                us["best"].append(u_of(l, best, m))
                us["worst"].append(u_of(l, worst, m))
                us["mean"].append(pooled([u_of(l, t, m) for t in finite]))
            row_u = {k: max((u for u in v if u is not None), default=None) for k, v in us.items()}
            rows.append([METRIC_LABELS[m], "best (frame)"] + [f"{fmt(m, s[0], row_u['best'])} ({s[1]})"
                                                             for s in stats.values()] + [fmt_u(row_u["best"])])
            rows.append(["", "worst (frame)"] + [f"{fmt(m, s[2], row_u['worst'])} ({s[3]})"
                                                 for s in stats.values()] + [fmt_u(row_u["worst"])])
            rows.append(["", "mean"] + [fmt(m, s[4], row_u["mean"]) for s in stats.values()] + [fmt_u(row_u["mean"])])
        tu = max((u for u in (res.temporal_u.get(l) for l in labels) if u is not None), default=None)
        rows.append([METRIC_LABELS["temporal"], "sequence"] + [fmt("temporal", res.temporal[l], tu) for l in labels]
                    + [fmt_u(tu)])
        jod = ""
        if res.jod:          # the columns the video metric judges (study.config.video)
            ju = max((u for l in labels for u in [res.jod_u.get(l, {}).get("sequence")] if u is not None), default=None)
            rows.append([METRIC_LABELS["jod"], f"video, {res.video['fps']:g} fps"]
                        + [fmt("jod", res.jod.get(l, {}).get("sequence"), ju) for l in labels] + [fmt_u(ju)])
            jod = (f" JOD: ColorVideoVDP {VIDEO_VERSION} of the {len(res.frames)} frames as a video at {res.video['fps']:g} "
                   f"fps on its '{res.video['display']}' display model (10 = no visible difference; higher is better).")
        elif self.video_off:
            jod = jod_off_note(res.width, res.height)
        rows.append([METRIC_LABELS["ms"], "median"] + [fmt("ms", res.ms[l]) for l in labels] + ["–"])
        note = (f"{res.test}: {len(res.frames)} frames at {res.width}x{res.height}, each against its own reference. "
                + floor_note(agree) + precision_note(res) + jod)
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "video": {l: a.get("video_key") for l, a in res.artefacts.items()},
                  "references": list(res.reference_keys.values())}
        self._table(f"{stem}_{res.scene}", Table(f"Ghosting test, {res.test}: {res.scene}", header, rows, note), inputs)
        self._file(f"plots/{stem}_{res.scene}.png", lambda: plots.series(res), inputs)
        if res.jod:        # ColorVideoVDP's map of the last frame, as a FLIP map and beside the others
            got: dict = {}

            def vmaps():
                if not got:
                    got.update({l: self.artefacts.video_map(res.artefacts[l], max(res.per_frame[l])) for l in res.jod})
                return got
            for l in res.jod:
                self._file(f"maps/{stem}_{res.scene}_{slug(l)}_cvvdp.png", lambda l=l: png(magma(vmaps()[l])),
                           {"video": res.artefacts[l]["video_key"]})
            self._file(f"plots/{stem}_cvvdp_{res.scene}.png", lambda: plots.vdp_maps(res, vmaps()), inputs)

    def ghosting_frames(self, res, reference, max_frames: int = 24) -> dict:
        """Display images of a ghosting sequence for the HTML report's frame slider (at most
        `max_frames`, evenly spaced), and its per-frame metrics. `reference(t)` gives frame t's
        Reference. Returns the html_report 'ghosting' entry of this protocol."""
        frames = shown_frames(res.frames, max_frames)     # the frames its runs keep (study.engine.plan)
        stem = f"ghosting_frames/{res.test}_{res.scene}"
        entry = {"frames": frames, "reference": [], "techniques": {}}
        cache: dict = {}

        def ref_of(t):
            if t not in cache:
                r = reference(t)
                cache[t] = (r, self.display(res.scene, t, res.width, res.height, r))
            return cache[t]
        for t in frames:
            rel = f"images/{stem}_reference_{t:04d}.png"
            key = {"reference": res.reference_keys.get(t)}
            self._file(rel, lambda t=t: png(ref_of(t)[1].to_8bit(ref_of(t)[0].image)), key, parallel=True)
            entry["reference"].append(rel)
        for label, a in res.artefacts.items():
            imgs = []
            for t in frames:
                rel = f"images/{stem}_{slug(label)}_{t:04d}.png"

                def image(a=a, t=t):
                    return png(self.artefacts.frame_8bit(a, t, ref_of(t)[1]))
                self._file(rel, image, {"run": a["run_key"], "frame": t, "reference": res.reference_keys.get(t)},
                           parallel=True)
                imgs.append(rel)
            entry["techniques"][label] = {
                "images": imgs,
                "metrics": {m: [res.per_frame[label][t].get(m) for t in frames] for m in GHOST_METRICS}}
        return entry

    # -- precision ---------------------------------------------------------------------------
    def precision(self, res) -> None:
        """figures.json (every figure with its reference uncertainty) and the precision table: per
        scene the bounds its references were refined through and the figures still over tolerance."""
        tests = [("static", r) for r in res.statics] + [(p, g) for p, gs in res.ghosts.items() for g in gs] \
            + [("sweep", s) for s in res.sweeps]
        doc = {"tolerances": res.tolerances, "precision": res.precision, "tests": [
            {"scene": r.scene, "protocol": p, "width": r.width, "height": r.height,
             "reference_bound_lsb": r.reference_bound_lsb,
             "techniques": {l: {"frames": {str(f): {"figures": v, "uncertainty": r.uncertainty.get(l, {}).get(f, {})}
                                           for f, v in per.items()},
                                "temporal": r.temporal.get(l), "temporal_u": r.temporal_u.get(l),
                                "jod": r.jod.get(l), "jod_u": r.jod_u.get(l)}
                            for l, per in r.per_frame.items()}} for p, r in tests]}
        inputs = {"metrics": sorted({a["metrics_key"] for _, r in tests for a in r.artefacts.values()}),
                  "video": sorted({a.get("video_key") or "" for _, r in tests for a in r.artefacts.values()}),
                  "precision": res.precision}
        # strict JSON, infinities as "inf" (study.reporting.encode.from_strict reads them back)
        self._file("tables/figures.json", lambda: strict_json(doc, infinity="inf", indent=1, sort_keys=True), inputs)
        if not res.precision:
            return
        rows = []
        for scene, per in sorted(res.precision.items()):
            for proto, p in sorted(per.items()):
                worst = max(p["over"], key=lambda x: x[4] / x[5] if x[5] else math.inf) if p["over"] else None
                final = ", ".join(f"{b} ({n})" for b, n in sorted(p.get("bounds", {}).items(), key=lambda x: -float(x[0])))
                rows.append([scene, proto, p["rule"], " → ".join(f"{b:g}" for b in p["rounds"]),
                             final if len(p.get("bounds", {})) > 1 else f"{p['bound_lsb']:g}",
                             str(len(p["over"])),
                             "–" if worst is None else f"{worst[3]} of {worst[1]} ±{worst[4]:.2g} > {worst[5]:.2g}"])
        tol = ", ".join(f"{k} {v:g}" for k, v in sorted(res.tolerances.items()))
        note = ("Each test's references are probed at a coarse per-pixel bound, then rendered at the bound its "
                "figures ask for, instant by instant (final: bound (instants at it)), and checked there, while any printed figure's reference uncertainty (its halves' plus its "
                "drift from the coarser bound) exceeds its tolerance (" + tol + "; relative and relmse as "
                "fractions of the figure). A ghosting test prints, and is refined for, " + ", ".join(
                    METRIC_LABELS[m] for m in GHOST_METRICS) + " and the temporal RMS; its frames are not "
                "judged in HDR.")
        self._table("reference_precision", Table("Reference precision: bounds set by the figures",
                                                 ["scene", "test", "rule", "bounds tried (LSB)", "final (LSB)",
                                                  "figures over", "worst"], rows, note), inputs)

    # -- findings ----------------------------------------------------------------------------
    def findings(self, res, variants: dict, alt: dict | None = None, study: dict | None = None) -> dict:
        """The thesis's claims adjudicated (study.reporting.findings): tables/findings.json, the
        claims table, the summary's LaTeX, and the sentences that open study.md. `study`: the
        study's profile, commit and date, which the record names (its 'study' field)."""
        from study.reporting import findings as F
        from study.reporting import findings_text as FT
        from study.reporting.encode import strict_json
        rec = F.findings(res, self.roles, variants, alt)
        if study:
            rec["study"] = dict(study)
        inputs = {"findings": hashlib.sha256(strict_json(rec, sort_keys=True).encode()).hexdigest()}
        self._file("tables/findings.json", strict_json(rec, indent=1, sort_keys=True), inputs)
        self._file("tables/findings_summary.tex", FT.latex_summary(rec), inputs)
        t = FT.table(rec)
        for ext, text in (("md", t.markdown()), ("csv", t.csv()), ("tex", t.latex())):
            self._file(f"tables/findings.{ext}", text, inputs)
        self.markdown.insert(0, FT.markdown(rec))
        return rec

    def finish(self, summary: dict) -> None:
        """study.md, then the files of the previous manifest this study did not write again are
        removed (an older run's; a file no manifest listed is the user's and stays), then the manifest."""
        for fut in self._pending:
            fut.result()            # an image that failed fails the report here
        if self._pool is not None:
            self._pool.shutdown()
        self._pool, self._pending = None, []      # a later parallel file starts a pool of its own
        self._file("study.md", "# TAA study\n\n" + "\n".join(self.markdown), {"tables": sorted(self.manifest)})
        removed = 0
        for rel in sorted(set(self.previous) - set(self.manifest)):
            path = self.out / rel
            if rel.split("/")[0] in self.FOLDERS and path.is_file():
                path.unlink()
                removed += 1
        self.summary = {**summary, "stale_files_removed": removed}
        self._write_manifest()

    def add(self, rel: str, data, inputs: dict) -> None:
        """Write and list a file made after finish (the HTML report, made from the finished folder)."""
        self._file(rel, data, inputs)
        self._write_manifest()

    def _write_manifest(self) -> None:
        # one artefact a line: json's indented encoder is pure Python (0.1-0.2 s for ~1600 entries,
        # written twice), its compact one is C
        one = lambda v: json.dumps(v, sort_keys=True, default=str)    # noqa: E731
        arts = ",\n".join(f"  {one(k)}: {one(v)}" for k, v in sorted(self.manifest.items()))
        write_text_atomic(self.out / "manifest.json",
                          f'{{\n "artefacts": {{\n{arts}\n }},\n "summary": {one(self.summary)}\n}}\n')


def jod_off_note(width: int, height: int) -> str:
    """A ghosting table's words where the study's [video] metric is "none": why it has no JOD and
    where one is (the cost: docs/guide.md, "Profiles"; the device: study.metrics.video)."""
    return (f" JOD not computed at {width}x{height}: this study's [video] metric is \"none\" (ColorVideoVDP costs "
            "about 6 s per technique-frame at 1600x900 on one CPU core, three times that with the reference's "
            "halves). The quick study's JOD at 320x180 is in its own ghosting tables (make study: "
            "out/quick/tables/ghosting_*). For one here, run with [video] metric = \"cvvdp\" on a CUDA device "
            "([video] device = \"auto\" uses it where torch sees one).")


def write_study(out: Path, res, configs, summary: dict, start: float) -> None:
    """Every table, image, map, plot and the interactive report of a study's results
    (study.engine.results.StudyResults) into `out`; the manifest lists exactly these files."""
    import time

    from study.config.profile import thesis_roles
    from study.reporting import ground_truth
    from study.reporting.findings import sharpen_variants
    from study.reporting import html_report
    report = Report(out, res.artefacts, thesis_roles(configs), res.display)
    report.video_off = summary.get("video_metric") == "none"
    report.draw_plots = os.environ.get(PLOTS_ENV) != "0"
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
    report.overview(views)
    report.reproduction(views, res.ghosts)
    variants = sharpen_variants(configs)
    report.sharpen_test(views, variants)
    report.sharpen_sweep(res.sharpen_sweeps)
    gt_label = ground_truth.label_of(configs)
    alt = ground_truth.figures(report, views, res.references, gt_label) if res.artefacts is not None else {}
    report.ground_truth(views, alt, gt_label)
    report.findings(res, variants, alt, {k: summary.get(k) for k in ("profile", "commit", "date")})
    converged = list(views.values())[-1] if views else []
    report.speed_error(converged)
    report.upscaling(converged, res.ghosts, configs, thesis_roles(configs).get("Uncharted"))
    report.history_convergence(res.statics, res.thesis_history)
    report.sparse_cost(converged + [g for gs in res.ghosts.values() for g in gs])
    report.convergence(res.references)
    report.precision(res)
    ghost_views = {}
    for pname, results in list(res.ghosts.items())[:1]:      # the first (the thesis's) ghosting protocol
        for g in results:
            ghost_views.setdefault(g.scene, {})[pname] = report.ghosting_frames(
                g, lambda t, g=g: res.reference(g.scene, t, g.width, g.height, g.test))
    report.finish({**summary, "seconds": round(time.perf_counter() - start, 2)})
    data = html_report.collect(out)
    for scene, gv in ghost_views.items():
        if scene in data["scenes"]:
            data["scenes"][scene]["ghosting"] = gv
    from study.reporting.findings_text import agreement_missed
    for scene, agree in res.agreements.items():
        if scene in data["scenes"]:
            data["scenes"][scene]["agreement"] = agree
            if agreement_missed(agree):
                data.setdefault("missed", {})[scene] = agreement_missed(agree)
    report.add("report.html", lambda: html_report.page(out, data), html_report.inputs_of(data))
