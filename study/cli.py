"""The `taa-study` command."""
from __future__ import annotations

import json
import sys

import click


def _fail(msg: str) -> None:
    click.echo(f"error: {msg}", err=True)
    sys.exit(2)


def _scene_and_size(name: str, profile: str, width: int | None, height: int | None):
    from scenes import SceneError, get_scene
    try:
        scene = get_scene(name)
        w, h = scene.resolution(profile)
    except SceneError as exc:
        _fail(str(exc))
    return scene, (w if width is None else width), (h if height is None else height)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def main():
    """Reference-and-comparison study of temporal anti-aliasing."""


@main.command()
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list instead of a table.")
def scenes(as_json):
    """List the built-in scenes."""
    from scenes import builtin_names, get_scene
    rows = []
    for name in builtin_names():
        s = get_scene(name)
        d = s.desc
        rows.append({"name": name, "frames": d.frames, "width": d.resolution.quick[0],
                     "height": d.resolution.quick[1], "full_width": d.resolution.full[0],
                     "full_height": d.resolution.full[1], "objects": len(d.objects),
                     "triangles": int(sum(len(m.faces) for m in s.meshes)), "lights": len(d.lights),
                     "transport": d.transport, "features": d.features(), "stresses": d.stresses})
    if as_json:
        click.echo(_strict_json(rows))
        return
    for r in rows:
        click.echo(f"{r['name']:16s} {r['frames']:4d} frames  quick {r['width']}x{r['height']}  "
                   f"full {r['full_width']}x{r['full_height']}  {r['objects']:3d} objects "
                   f"{r['triangles']:6d} tris  {r['transport']:15s} {', '.join(r['features'])}")
        click.echo(f"{'':16s} stresses: {r['stresses']}")


def _print_agreement(a) -> None:
    from study.agreement import TARGETS
    ok = a.meets_targets()
    mark = {True: "ok", False: "BELOW TARGET"}
    click.echo(f"scene {a.scene}, frame {a.frame}, {a.width}x{a.height}")
    click.echo(f"  agreement PSNR (display, {a.raster_samples} raster frames vs reference): "
               f"{a.agreement_psnr_db:.2f} dB  [target >= {TARGETS['agreement_psnr_db']}: {mark[ok['agreement_psnr_db']]}]")
    click.echo(f"  relative MSE (linear HDR): {a.relative_mse:.3e}")
    click.echo(f"  interior max |raster - Mitsuba ray| at pixel centres: {a.interior_max_abs_err:.2e} "
               f"over {a.interior_pixels} pixels  [target <= {TARGETS['interior_max_abs_err']:g}: "
               f"{mark[ok['interior_max_abs_err']]}]")
    click.echo(f"  reference: {a.reference_spp} spp mean, {a.reference_spp_max} max, {a.reference_seconds:.1f} s"
               f"{' (cached)' if a.reference_cached else ''}, noise PSNR {a.reference_noise_psnr_db:.2f} dB"
               f"  [target >= {TARGETS['reference_noise_psnr_db']}: {mark[ok['reference_noise_psnr_db']]}]")
    click.echo(f"  reference per-pixel SE: bound {a.reference_se_bound_lsb:g} LSB, p99.9 {a.reference_se_p999_lsb:.3f}, "
               f"max {a.reference_se_max_lsb:.3f}, {a.reference_over_bound} pixels over  "
               f"[{'held' if ok['reference_bound'] else 'BOUND MISSED'}]")
    click.echo(f"  objects visible at {100 * a.visible_fraction:.1f} % of pixel centres  "
               f"[{'ok' if ok['objects_visible'] else 'NOTHING TO COMPARE: background only'}]")
    click.echo(f"  single sample per pixel: {a.single_sample} (pixel centres matching a single ray: "
               f"{100 * a.centre_match_fraction:.3f} %)")


@main.command()
@click.option("--scene", "scene_names", multiple=True, help="Built-in scene name or scene file (repeatable).")
@click.option("--all", "all_builtin", is_flag=True, help="Every built-in scene.")
@click.option("--frame", default=0, show_default=True, help="Frame index of the scene's animation.")
@click.option("--profile", type=click.Choice(["quick", "full"]), default="quick", show_default=True)
@click.option("--width", type=click.IntRange(min=8), help="Override the profile's width.")
@click.option("--height", type=click.IntRange(min=8), help="Override the profile's height.")
@click.option("--samples", default=256, show_default=True, type=click.IntRange(min=1),
              help="Jittered raster frames averaged.")
@click.option("--target-noise-db", default=60.0, show_default=True,
              help="Reference convergence target (display-domain noise PSNR).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (a list with several scenes).")
def agree(scene_names, all_builtin, frame, profile, width, height, samples, target_noise_db, as_json):
    """Prove the raster and the Mitsuba reference agree on one scene frame.

    Exits 1 when a scene misses a target (agreement >= 45 dB, interior error <= 1e-4,
    reference noise >= 55 dB, every reference pixel within its SE bound, single-sample raster,
    objects visible)."""
    from scenes import builtin_names
    names = list(scene_names) + (builtin_names() if all_builtin else [])
    if not names:
        _fail("name a scene with --scene NAME or use --all")
    if samples < 1:
        _fail(f"--samples must be >= 1, got {samples}")
    from study.agreement import check_agreement
    results = []
    for name in names:
        scene, w, h = _scene_and_size(name, profile, width, height)
        if frame < 0 or frame >= scene.desc.frames:
            _fail(f"scene {name!r} has frames 0..{scene.desc.frames - 1}; --frame {frame} is out of range")
        a = check_agreement(scene, w, h, frame=frame, samples=samples, target_noise_db=target_noise_db,
                            progress=not as_json)
        results.append(a)
        if not as_json:
            _print_agreement(a)
    if as_json:
        out = [a.as_dict() for a in results]
        click.echo(_strict_json(out[0] if len(out) == 1 else out))
    if not all(all(a.meets_targets().values()) for a in results):
        sys.exit(1)


@main.command()
@click.option("--scene", "scene_name", required=True, help="Built-in scene name or scene file.")
@click.option("--frame", default=0, show_default=True)
@click.option("--profile", type=click.Choice(["quick", "full"]), default="quick", show_default=True)
@click.option("--width", type=click.IntRange(min=8), help="Override the profile's width.")
@click.option("--height", type=click.IntRange(min=8), help="Override the profile's height.")
@click.option("--jitter", nargs=2, type=float, default=(0.0, 0.0), show_default=True,
              help="Sub-pixel offset (ox, oy) of the raster frame's sample.")
@click.option("--buffers", default="color,albedo,depth,object_id,motion", show_default=True,
              help="Comma-separated raster buffers to write.")
@click.option("--no-reference", is_flag=True, help="Write the raster buffers only.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True)
def render(scene_name, frame, profile, width, height, jitter, buffers, no_reference, out_dir):
    """Write one frame's raster buffers (EXR) and its reference (EXR + display PNG)."""
    from pathlib import Path

    import numpy as np
    from PIL import Image

    from display import DisplayTransform
    from raster import BUFFERS, Rasterizer
    from references import ReferenceCache
    from references.exr import write_exr

    scene, w, h = _scene_and_size(scene_name, profile, width, height)
    wanted = [b.strip() for b in buffers.split(",") if b.strip()]
    bad = [b for b in wanted if b not in BUFFERS]
    if bad:
        _fail(f"unknown buffer(s) {bad}; available: {', '.join(BUFFERS)}")
    if not 0 <= frame < scene.desc.frames:
        _fail(f"scene {scene.name!r} has frames 0..{scene.desc.frames - 1}; --frame {frame} is out of range")
    out = Path(out_dir)
    r = Rasterizer(scene, w, h)
    try:
        bufs = r.render(frame, jitter, wanted)
    finally:
        r.close()
    stem = f"{scene.name}_f{frame:04d}"
    for name, a in bufs.items():
        a = a.astype(np.float32)
        chans = {"RGB": a} if a.ndim == 3 and a.shape[2] == 3 else \
            {f"{name}.{'xy'[k]}": a[..., k] for k in range(a.shape[2])} if a.ndim == 3 else {name: a}
        write_exr(out / f"{stem}_{name}.exr", chans, {"taa_jitter": f"{jitter[0]} {jitter[1]}"})
    disp = None
    if not no_reference:
        ref, cached = ReferenceCache().get(scene, frame, w, h)
        write_exr(out / f"{stem}_reference.exr", {"RGB": ref.image}, {"taa_spp": ref.spp})
        disp = DisplayTransform.from_reference(ref.image)
        Image.fromarray(disp.to_8bit(ref.image)).save(out / f"{stem}_reference.png")
        click.echo(f"reference: {ref.spp} spp, noise PSNR {ref.noise_psnr_db:.1f} dB"
                   f"{' (cached)' if cached else ''}")
    if "color" in bufs:
        disp = disp or DisplayTransform.from_reference(bufs["color"])
        Image.fromarray(disp.to_8bit(bufs["color"])).save(out / f"{stem}_raster.png")
    click.echo(f"wrote {len(list(out.glob(stem + '*')))} files to {out}/")


def _scene_list(ctx, param, value):
    """Comma-separated scenes: empty items refused, duplicates dropped with a note."""
    if value is None:
        return None
    items = [v.strip() for v in value.split(",")]
    if not any(items) or any(not v for v in items):
        raise click.BadParameter(f"{value!r} names an empty scene; give comma-separated scene names or files")
    out = list(dict.fromkeys(items))
    if len(out) < len(items):
        dup = sorted({v for v in items if items.count(v) > 1})
        click.echo(f"note: {param.opts[0]}: duplicate scene(s) {', '.join(dup)} taken once", err=True)
    return out


def _executor(workers, threads, scheduler):
    from study.execute import Executor
    if scheduler and workers:
        _fail("give either --workers N (a local cluster) or --scheduler ADDRESS, not both")
    if scheduler:
        return Executor("scheduler", address=scheduler, threads=threads)
    if workers:
        return Executor("local", workers=workers, threads=threads)
    return Executor("in-process", threads=threads)


def _strict_json(obj) -> str:
    """One strict JSON document: NaN and infinities (undefined or unbounded figures) become null."""
    import math

    def clean(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o
    return json.dumps(clean(obj), allow_nan=False, default=str)


EXECUTION_OPTIONS = [
    click.option("--workers", type=click.IntRange(min=1), default=None,
                 help="Run the tasks on a local Dask cluster of N worker processes."),
    click.option("--threads", type=click.IntRange(min=1), default=None,
                 help="Dr.Jit threads per process (default: all cores)."),
    click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
                 help="Run the tasks on an existing Dask scheduler (the cache must be on a filesystem every "
                      "worker sees)."),
]


def _execution_options(f):
    for opt in reversed(EXECUTION_OPTIONS):
        f = opt(f)
    return f


def _techniques(tech_list, default=()):
    from study.config import TechniqueConfig, available
    try:
        configs = [TechniqueConfig.parse(t) for t in tech_list] if tech_list else list(default)
    except ValueError as exc:
        _fail(str(exc))
    configs, missing = available(configs)
    if missing:
        from study.config import resolve_technique
        try:
            resolve_technique(missing[0].name)
        except ValueError as exc:
            _fail(str(exc))
    labels = [c.label for c in configs]
    if len(set(labels)) != len(labels):
        _fail(f"technique labels must be unique, got {labels}")
    try:
        for c in configs:
            c.make()
    except (TypeError, ValueError, KeyError) as exc:
        _fail(f"bad technique parameters: {exc}")
    return configs


def _profile(study_file, profile):
    from study.config import get_profile
    from study.studyfile import StudyFileError
    try:
        return get_profile(study_file or profile)
    except StudyFileError as exc:
        _fail(str(exc))


def _load_scenes(names):
    from scenes import SceneError
    from study.tasks import load_scene
    try:
        return [load_scene(n) for n in names]
    except SceneError as exc:
        _fail(str(exc))


def run_study(profile, names, configs, out_dir, no_agreement, executor, sweep=True):
    """The study end to end: plan and execute its tasks (study.run), then write its tables, figures
    and report (study.report.write_study). `profile`: a Profile (study file). Returns the folder."""
    import time as _time
    from pathlib import Path

    from study.config import SPARSE_SWEEP
    from study.report import write_study
    from study.run import Study
    from study.tasks import TaskError

    start = _time.perf_counter()
    _load_scenes(names)
    study = Study(profile, executor=executor)
    sweep_cfg = SPARSE_SWEEP if sweep else ()
    try:
        res = study.run(names, configs, agreement=not no_agreement, sweep=sweep_cfg)
    except TaskError as exc:
        _fail(str(exc))
    out = Path(out_dir or study.profile.out or f"out/{study.profile.name}")
    summary = {**res.stats, "profile": study.profile.name, "scenes": names,
               "techniques": [c.label for c in configs], "executor": executor.describe()}
    write_study(out, study, res, configs, summary, start)
    click.echo((out / "tables" / "headline.md").read_text())
    if (out / "tables" / "reproduction.md").exists():
        click.echo((out / "tables" / "reproduction.md").read_text())
    click.echo(f"runs computed {res.stats['runs_computed']}, cached {res.stats['runs_cached']}; "
               f"metrics computed {res.stats['metrics_computed']}; references rendered "
               f"{res.stats['references_rendered']}; {_time.perf_counter() - start:.1f} s; artefacts in {out}/, "
               f"report {out / 'report.html'}")
    return out


PROFILE_OPTION = click.option("--profile", type=click.Choice(["quick", "full"]), default="quick", show_default=True,
                              help="A built-in study file (study/profiles/); STUDY_FILE replaces it.")


@main.command()
@click.argument("study_file", required=False, type=click.Path(dir_okay=False))
@PROFILE_OPTION
@click.option("--scenes", "scene_list", default=None, callback=_scene_list,
              help="Comma-separated scenes (default: the study file's, or every built-in).")
@click.option("--techniques", "tech_list", multiple=True,
              help="Technique as 'name', 'file.py:Class' or 'Label=name:field=value,...' (repeatable; "
                   "default: the study file's).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Output folder (default: the study file's, or out/<name>); it keeps only this study's files.")
@click.option("--no-agreement", is_flag=True, help="Skip the per-scene reference agreement figure.")
@_execution_options
def run(study_file, profile, scene_list, tech_list, out_dir, no_agreement, workers, threads, scheduler):
    """Run a study (a study file, or a built-in profile) and write tables, maps and plots (make-style)."""
    from scenes import builtin_names
    prof = _profile(study_file, profile)
    names = scene_list or list(prof.scenes) or builtin_names()
    configs = _techniques(tech_list, prof.techniques)
    run_study(prof, names, configs, out_dir, no_agreement or not prof.agreement,
              _executor(workers, threads, scheduler), sweep=prof.sweep and not tech_list)


@main.command()
@click.argument("study_file", required=False, type=click.Path(dir_okay=False))
@PROFILE_OPTION
@click.option("--scenes", "scene_list", default=None, callback=_scene_list,
              help="Comma-separated scenes (default: the study file's, or every built-in).")
@click.option("--measure/--no-measure", default=False, show_default=True,
              help="Time one unit of each kind per scene here (renders and caches frame 0's reference) "
                   "and extrapolate the study's wall time.")
@click.option("--from-scratch", is_flag=True,
              help="Count the whole study's work as on an empty cache (the units are still measured with the cache).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the table.")
def estimate(study_file, profile, scene_list, measure, from_scratch, as_json):
    """What a study would compute (work units per scene, only what the cache lacks) and, with
    --measure, what that costs on this machine, extrapolated from one unit of each kind."""
    from scenes import builtin_names
    from study import estimate as E
    from study.config import SPARSE_SWEEP
    from study.run import Study
    from study.tasks import TaskError
    prof = _profile(study_file, profile)
    names = scene_list or list(prof.scenes) or builtin_names()
    configs = _techniques((), prof.techniques)
    _load_scenes(names)
    import tempfile
    from pathlib import Path
    study = Study(prof, progress=False)
    with tempfile.TemporaryDirectory() as empty:
        planner = Study(prof, cache_root=Path(empty), progress=False) if from_scratch else study
        plan = planner.plan(names, configs, agreement=prof.agreement, sweep=SPARSE_SWEEP if prof.sweep else ())[0]
        work = E.work(plan, None if from_scratch else study.cache)
    rows, totals = [], {}
    for name, sw in work.items():
        row = {"scene": name, "resolution": [sw.width, sw.height], "references": sw.references,
               "raster_frames": sw.raster_frames, "subframes": sum(sw.subframes.values()),
               "technique_steps": sum(sw.steps.values()), "technique_frames_judged": sum(sw.judged.values()),
               "agreement_frames": sw.agreement_frames}
        if measure:
            click.echo(f"estimate: measuring {name} at {sw.width}x{sw.height} ...", err=True)
            try:
                units = E.measure_units(sw, study.ref_settings, study.cache,
                                        [c for c in configs if c.label in sw.configs] or configs[:1])
            except TaskError as exc:
                _fail(str(exc))
            row["unit_s"] = {k: v for k, v in units.items() if k != "subframe_s"}
            row["seconds"] = E.estimate(sw, units)
            for k, v in row["seconds"].items():
                totals[k] = totals.get(k, 0.0) + v
        rows.append(row)
    doc = {"study": prof.name, "tasks": plan.counts(), "complete": len(plan.cached), "scenes": rows}
    if measure:
        doc["seconds"] = totals
    if as_json:
        click.echo(_strict_json(doc))
        return
    click.echo(f"{prof.name}: tasks to compute {plan.counts() or 'none'}, {len(plan.cached)} complete")
    head = "scene | res | refs | raster | subframes | steps | judged | agreement"
    if measure:
        head += " | ref s/frame | metrics s/frame | est. ref min | est. total min"
    click.echo(head)
    for r in rows:
        line = (f"{r['scene']} | {r['resolution'][0]}x{r['resolution'][1]} | {r['references']} | "
                f"{r['raster_frames']} | {r['subframes']} | {r['technique_steps']} | "
                f"{r['technique_frames_judged']} | {r['agreement_frames']}")
        if measure:
            u, sec = r["unit_s"], r["seconds"]
            line += (f" | {u['reference_s']:.1f} | {u['metrics_s']:.3f} | {sec['reference'] / 60:.1f}"
                     f" | {sec['total'] / 60:.1f}")
        click.echo(line)
    if measure:
        click.echo("extrapolated minutes: " + ", ".join(f"{k} {v / 60:.1f}" for k, v in totals.items())
                   + " (references of moving scenes taken at frame 0's cost)")


def _technique_names(ctx, param, value):
    if not value:
        return value
    import taa_impl
    bad = [v for v in value if v not in taa_impl.TECHNIQUES]
    if bad:
        raise click.BadParameter(f"unknown technique(s) {', '.join(bad)}; known: {', '.join(sorted(taa_impl.TECHNIQUES))}")
    return tuple(dict.fromkeys(value))


@main.command()
@click.option("--width", default=1600, show_default=True, type=click.IntRange(min=8))
@click.option("--height", default=900, show_default=True, type=click.IntRange(min=8))
@click.option("--repeats", default=7, show_default=True, type=click.IntRange(min=1),
              help="Timed runs per technique (median).")
@click.option("--technique", "tech_names", multiple=True, callback=_technique_names,
              help="Only these techniques (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def bench(width, height, repeats, tech_names, as_json):
    """Time each technique per frame against its NumPy oracle and the bandwidth floor."""
    from study.bench import bench as run_bench
    res = run_bench(width, height, repeats, list(tech_names) or None,
                    log=(lambda m: None) if as_json else (lambda m: click.echo(m, err=True)))
    if as_json:
        click.echo(_strict_json(res))
        return
    click.echo(f"{width}x{height}, backend {res['backend']}, copy bandwidth {res['copy_bandwidth_gbs']:.2f} GB/s")
    click.echo(f"{'technique':24s} {'Dr.Jit ms':>10s} {'e2e ms':>8s} {'NumPy ms':>10s} {'speed-up':>9s} "
               f"{'floor ms':>9s} {'x floor':>8s}")
    for name, t in res["techniques"].items():
        ms, floor = t["ms"], res["bandwidth_floor_ms"][name]
        npm = res["numpy_ms"].get(name)
        click.echo(f"{name:24s} {ms:10.2f} {res['end_to_end_ms'][name]:8.2f} "
                   f"{(f'{npm:10.1f}' if npm else '         –')} {(f'{npm / ms:8.1f}x' if npm else '        –')} "
                   f"{floor:9.2f} {ms / floor:7.1f}x")


@main.command()
@click.argument("a")
@click.argument("b")
@click.option("--scenes", "scene_list", default=None, callback=_scene_list,
              help="Comma-separated scenes (default: the study file's, or pipe,sphere_ghosting).")
@PROFILE_OPTION
@click.option("--study", "study_file", type=click.Path(dir_okay=False), default=None,
              help="A study file for the scenes, resolution, protocols and reference settings.")
@click.option("--max-worse", "gates", multiple=True,
              help="METRIC=THRESHOLD: exit 1 if B is worse than A by more than THRESHOLD on average "
                   "(e.g. psnr=0.25, ssim=0.002, mse=1.0, flip_ldr=0.002). Repeatable.")
@click.option("--json", "as_json", is_flag=True, help="Print one strict JSON object (nothing else on stdout).")
@_execution_options
def ab(a, b, scene_list, profile, study_file, gates, as_json, workers, threads, scheduler):
    """Compare technique configuration B against A: paired differences with bootstrap intervals.

    A and B are 'name' or 'Label=name:field=value,...', e.g.
    taa-study ab taa_baseline "taa_baseline:sharpen=normalised" --max-worse psnr=0.25"""
    from study.ab import AB_METRICS, compare
    from study.run import Study
    from study.tasks import TaskError
    ca, cb = _techniques((a, b)) if a != b else (_techniques((a,))[0], _techniques((a,))[0])
    prof = _profile(study_file, profile)
    scene_list = scene_list or list(prof.scenes) or ["pipe", "sphere_ghosting"]
    _load_scenes(scene_list)
    limits = {}
    for g in gates:
        m, eq, v = g.partition("=")
        if not eq or m not in AB_METRICS:
            _fail(f"--max-worse {g!r}: expected METRIC=THRESHOLD with METRIC in {', '.join(AB_METRICS)}")
        try:
            limits[m] = float(v)
        except ValueError:
            _fail(f"--max-worse {g!r}: threshold {v!r} is not a number")
    try:
        res = compare(ca, cb, scene_list, prof, progress=not as_json,
                      study=Study(prof, progress=not as_json, executor=_executor(workers, threads, scheduler)))
    except TaskError as exc:
        _fail(str(exc))
    failed = {m: res.worse_by(m) for m, lim in limits.items() if res.worse_by(m) > lim}
    if as_json:
        click.echo(_strict_json({**res.as_dict(), "gates": limits, "failed": failed}))
    else:
        click.echo(f"B = {res.b}  vs  A = {res.a}   (differences B - A, mean [95 % bootstrap CI], n pairs)")
        for scene, per in list(res.per_scene.items()) + [("OVERALL", res.overall)]:
            cells = []
            for m, v in per.items():
                ci = f"[{v['ci'][0]:+.3g}, {v['ci'][1]:+.3g}]" if v["ci"] else "[no interval: one pair]"
                mean = "–" if v["mean"] is None else f"{v['mean']:+.4g}"
                cells.append(f"{m} {mean} {ci} n={v['n']}")
            click.echo(f"  {scene:18s} " + "; ".join(cells))
        click.echo(f"  cost: A {res.ms['a']:.2f} ms, B {res.ms['b']:.2f} ms per frame ({res.ms['diff']:+.2f} ms)")
        for m, w in failed.items():
            click.echo(f"  GATE FAILED: B is worse than A on {m} by {w:.4g} (> {limits[m]})")
    if failed:
        sys.exit(1)


@main.command()
@click.argument("study_file", required=False, type=click.Path(dir_okay=False))
@PROFILE_OPTION
@click.option("--scenes", "scene_list", default=None, callback=_scene_list,
              help="Comma-separated scenes (default: the study file's, or every built-in).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="The study's output folder (default: the study file's, or out/<name>).")
@click.option("--no-pdf", is_flag=True, help="Only regenerate paper/generated/, do not run LaTeX.")
@_execution_options
def paper(study_file, profile, scene_list, out_dir, no_pdf, workers, threads, scheduler):
    """Regenerate the study, copy its tables and figures into paper/generated/, build the PDF."""
    from pathlib import Path

    from scenes import builtin_names
    from study import paper_pdf

    prof = _profile(study_file, profile)
    src = run_study(prof, scene_list or list(prof.scenes) or builtin_names(), _techniques((), prof.techniques),
                    out_dir, not prof.agreement, _executor(workers, threads, scheduler), sweep=prof.sweep)
    root = Path(__file__).resolve().parent.parent / "paper"
    got = paper_pdf.fill_generated(src, root)       # only what this study's manifest lists
    click.echo(f"paper/generated/: {len(got['tables'])} tables, {len(got['figures'])} figures")
    if no_pdf:
        return
    try:
        pdf = paper_pdf.build_pdf(root)
    except paper_pdf.PaperError as exc:
        _fail(str(exc))
    info = paper_pdf.contents(root)
    click.echo(f"built {pdf} ({info.get('pages', '?')} pages)")
