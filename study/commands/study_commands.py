"""The commands that run studies: `run`, `estimate`, `bench`, `ab` and `paper`."""
from __future__ import annotations

import math
import sys

from pathlib import Path

import click

from scenes.description import MAX_SIDE
from study.commands.common import (PROFILE_OPTION, _cache_folder, _execution_options, _executor, _fail,
                                   _load_scenes, _profile, _scene_list, _strict_json, _techniques, main,
                                   run_study)

PAPER_DIR = Path(__file__).resolve().parents[2] / "paper"       # the checkout's paper/ (main.tex)

_UNIT_SECONDS = {"s": 1.0, "m": 60.0, "h": 3600.0, "d": 86400.0}


def parse_duration(text: str) -> float:
    """Seconds of a duration such as '90m', '2h', '3600s', '1h30m' or '1.5h' (units s, m, h, d;
    at least one, each a number >= 0). ValueError otherwise."""
    import re
    t = text.strip().lower()
    parts = re.findall(r"(\d+(?:\.\d+)?)([smhd])", t)
    if not t or not parts or "".join(n + u for n, u in parts) != t:
        raise ValueError("expected a duration such as 90m, 2h, 3600s or 1h30m (units s, m, h, d)")
    return sum(float(n) * _UNIT_SECONDS[u] for n, u in parts)


def _deadline(ctx, param, value):
    """--stop-after's value as the deadline (study.engine.execute.now() + the duration), from now."""
    if value is None:
        return None
    try:
        seconds = parse_duration(value)
    except ValueError as exc:
        raise click.BadParameter(f"{value!r}: {exc}") from None
    from study.engine.execute import now
    return now() + seconds


STOP_AFTER_OPTION = click.option(
    "--stop-after", "deadline", default=None, metavar="DURATION", callback=_deadline,
    help="Start no task after DURATION (e.g. 90m, 2h, 3600s) from now: the tasks in flight finish, "
         "nothing is written for the unfinished study, and it exits with status 3; the same command "
         "again resumes it, recomputing nothing that finished.")


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
@click.option("--precision", "rule", type=click.Choice(["figures", "per_pixel"]), default=None,
              help="References refined until every figure is within its tolerance ('figures'), or every "
                   "reference at the [reference] per-pixel bound ('per_pixel'); default: the study file's.")
@STOP_AFTER_OPTION
@_execution_options
def run(study_file, profile, scene_list, tech_list, out_dir, no_agreement, rule, deadline, workers, threads,
        scheduler):
    """Run a study (a study file, or a built-in profile) and write tables, maps and plots (make-style)."""
    import dataclasses

    from scenes import builtin_names
    prof = _profile(study_file, profile)
    if rule is not None:
        prof = dataclasses.replace(prof, precision=dataclasses.replace(prof.precision, rule=rule))
    names = scene_list or list(prof.scenes) or builtin_names()
    configs = _techniques(tech_list, prof.techniques)
    run_study(prof, names, configs, out_dir, no_agreement or not prof.agreement,
              _executor(workers, threads, scheduler), sweep=prof.sweep and not tech_list, own_columns=not tech_list,
              deadline=deadline)


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
    from study.engine import estimate as E
    from study.config.profile import SPARSE_SWEEP, sharpen_sweep_configs
    from study.engine.runner import Study
    from study.engine.tasks import TaskError
    from study.engine.tasks import load_scene as _load
    prof = _profile(study_file, profile)
    names = scene_list or list(prof.scenes) or builtin_names()
    configs = _techniques((), prof.techniques)
    _load_scenes(names)
    import tempfile
    from pathlib import Path
    _cache_folder()
    study = Study(prof, progress=False)
    with tempfile.TemporaryDirectory() as empty:
        planner = Study(prof, cache_root=Path(empty), progress=False) if from_scratch else study
        plan = planner.plan(names, configs, agreement=prof.agreement, sweep=SPARSE_SWEEP if prof.sweep else (),
                            sharpen=sharpen_sweep_configs(prof.sharpen_sweep))[0]
        work = E.work(plan, None if from_scratch else study.cache)
        from study.engine import disk as D
        need = D.needs(plan)
    # what the run plans for: the profile's policy (runs pruned once judged, or whole while they refine)
    pruned = prof.runs_while_refining == "pruned" or study.precision.rule != "figures"
    removing = None if study.precision.rule != "figures" else not prof.keep_superseded
    budget = None if prof.disk_budget_gb is None else int(prof.disk_budget_gb * 2 ** 30)
    disk = D.summary(need, D.free_bytes(study.cache.root), pruned, removing, budget)
    rows, totals = [], {}
    for name, sw in work.items():
        row = {"scene": name, "resolution": [sw.width, sw.height], "references": sw.references,
               "raster_frames": sw.raster_frames, "subframes": sum(sw.subframes.values()),
               "technique_steps": sum(sw.steps.values()), "technique_frames_judged": sum(sw.judged.values()),
               "technique_frames_written": sw.written,
               "agreement_frames": sw.agreement_frames, "run_memory_bytes": sw.run_memory}
        if measure:
            click.echo(f"estimate: measuring {name} at {sw.width}x{sw.height} ...", err=True)
            try:
                units = E.measure_units(sw, study.settings_for(name), study.cache,
                                        [c for c in configs if c.label in sw.configs] or configs[:1])
                if study.precision.rule == "figures":
                    # a probe, then the bound the figures ask for (study.engine.precision), which
                    # only the run knows: priced at the per-pixel [reference] bound
                    final = study.cache.get(_load(sw.spec), 0, sw.width, sw.height, **study.ref_settings)[0]
                    units["reference_s"] += final.seconds
            except TaskError as exc:
                _fail(str(exc))
            row["unit_s"] = {k: v for k, v in units.items() if k != "subframe_s"}
            row["seconds"] = E.estimate(sw, units)
            for k, v in row["seconds"].items():
                totals[k] = totals.get(k, 0.0) + v
        rows.append(row)
    doc = {"study": prof.name, "tasks": plan.counts(), "to_compute": plan.to_compute(), "complete": plan.complete(),
           "scenes": rows, "disk": disk,
           "memory": _memory_need(prof, names, work)}
    if measure:
        doc["seconds"] = totals
    if as_json:
        click.echo(_strict_json(doc))
        return
    click.echo(f"{prof.name}: tasks to compute {plan.to_compute() or 'none'}, {plan.complete()} complete")
    remake = sum(r["seconds"]["raster"] + r["seconds"]["resolve"] for r in rows) if measure else None
    for line in D.describe(disk, remake):
        click.echo(line)
    mem = doc["memory"]
    click.echo(f"memory: about {mem['per_process_gb']:.1f} GB per process at its largest ({mem['what']}, "
               f"{mem['width']}x{mem['height']}, scene {mem['scene']}), {mem['processes']} at once by default: "
               f"{mem['need_gb']:.1f} GB; {mem['available_gb']:.1f} GB available"
               + ("  [MORE THAN AVAILABLE: fewer --workers or a smaller resolution]" if mem["need_gb"] > mem["available_gb"]
                  else "") + " (raster.limits, study.engine.estimate.run_memory)")
    head = "scene | res | refs | raster | subframes | steps | judged | agreement"
    if measure:
        head += " | ref s/frame | metrics s/frame | est. ref min | est. total min"
    click.echo(head)
    for r in rows:
        line = (f"{r['scene']} | {r['resolution'][0]}x{r['resolution'][1]} | {r['references']} | "
                f"{r['raster_frames']:g} | {r['subframes']} | {r['technique_steps']} | "
                f"{r['technique_frames_judged']} | {r['agreement_frames']}")
        if measure:
            u, sec = r["unit_s"], r["seconds"]
            line += (f" | {u['reference_s']:.1f} | {u['metrics_s']:.3f} | {sec['reference'] / 60:.1f}"
                     f" | {sec['total'] / 60:.1f}")
        click.echo(line)
    if measure:
        click.echo("extrapolated minutes: " + ", ".join(f"{k} {v / 60:.1f}" for k, v in totals.items())
                   + " (references of moving scenes taken at frame 0's cost"
                   + ("; each a probe plus a render at the [reference] bound, where the figures' rule may ask"
                      " more or less)" if study.precision.rule == "figures" else ")"))


def _memory_need(prof, names, work: dict) -> dict:
    """The memory a study needs per process: the larger of a render at its largest size
    (raster.limits) and its largest run task (study.engine.estimate.run_memory: the raster frames
    a test keeps and its columns), and for the processes the default executor runs at once."""
    from raster.limits import available_memory, memory_need
    from study.commands.common import _study_size
    from study.engine.execute import Executor
    sizes = {n: _study_size(prof, n) for n in names}
    scene = max(sizes, key=lambda n: sizes[n][0] * sizes[n][1])
    w, h = sizes[scene]
    per, what = memory_need(w, h), "a render"
    runs = {n: sw.run_memory for n, sw in work.items() if sw.run_memory}
    if runs and max(runs.values()) > per:
        scene = max(runs, key=runs.get)
        (w, h), per, what = (work[scene].width, work[scene].height), runs[scene], "a run task"
    ex = Executor.auto()
    procs = ex.workers if ex.kind == "auto" else 1
    gb = 2 ** 30
    return {"scene": scene, "width": w, "height": h, "what": what, "per_process_gb": per / gb, "processes": procs,
            "need_gb": per * procs / gb, "available_gb": available_memory() / gb}


def _technique_names(ctx, param, value):
    if not value:
        return value
    import taa_impl
    bad = [v for v in value if v not in taa_impl.TECHNIQUES]
    if bad:
        raise click.BadParameter(f"unknown technique(s) {', '.join(bad)}; known: {', '.join(sorted(taa_impl.TECHNIQUES))}")
    return tuple(dict.fromkeys(value))


@main.command()
@click.option("--width", default=1600, show_default=True, type=click.IntRange(min=8, max=MAX_SIDE))
@click.option("--height", default=900, show_default=True, type=click.IntRange(min=8, max=MAX_SIDE))
@click.option("--repeats", default=7, show_default=True, type=click.IntRange(min=1),
              help="Timed runs per technique (median).")
@click.option("--technique", "tech_names", multiple=True, callback=_technique_names,
              help="Only these techniques (repeatable).")
@click.option("--render-scale", "scale_text", default=None, metavar="S[,S...]",
              help="The upscalers' render scales, one entry each (default: the full study's, 0.5,0.67,0.77,1).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def bench(width, height, repeats, tech_names, scale_text, as_json):
    """Time each technique per frame (each upscaler at each render scale) against its NumPy oracle
    and the bandwidth floor."""
    from study.commands.bench import RENDER_SCALES
    from study.commands.bench import bench as run_bench
    scales = _scales(scale_text) or RENDER_SCALES
    res = run_bench(width, height, repeats, list(tech_names) or None, render_scales=scales,
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


def _scales(text):
    """--render-scale's value: distinct scales in [0.1, 1] (exit 2 otherwise)."""
    if text is None:
        return None
    from taa_impl.upscale import check_scale
    try:
        scales = [check_scale(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        _fail(f"--render-scale {text!r}: {exc}")
    if not scales or len(set(scales)) != len(scales):
        _fail(f"--render-scale {text!r}: give distinct scales, e.g. 0.5,0.67")
    return scales


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
                   "(e.g. psnr=0.25, ssim=0.002, mse=1.0, flip_ldr=0.002, jod=0.1). Repeatable.")
@click.option("--video/--no-video", default=True, show_default=True,
              help="Judge A and B by the video metric (ColorVideoVDP, JOD) where the study's [video] judges a "
                   "scene; --no-video skips it (~0.3 s a technique-frame at 320x180, plus ~10 s to load torch).")
@click.option("--render-scale", "render_scale", default=None, callback=lambda ctx, p, v: _scales(v),
              help="Comma-separated render scales of an upscaler A or B (taa_impl.upscale): one comparison "
                   "per scale, e.g. 0.5,0.67.")
@click.option("--json", "as_json", is_flag=True, help="Print one strict JSON object (nothing else on stdout).")
@STOP_AFTER_OPTION
@_execution_options
def ab(a, b, scene_list, profile, study_file, gates, video, render_scale, as_json, deadline, workers, threads,
       scheduler):
    """Compare technique configuration B against A: paired differences with bootstrap intervals.

    A and B are 'name' or 'Label=name:field=value,...', e.g.
    taa-study ab taa_baseline "taa_baseline:sharpen=normalised" --max-worse psnr=0.25"""
    from study.commands.ab import AB_METRICS
    ca, cb = _techniques((a, b)) if a != b else (_techniques((a,))[0], _techniques((a,))[0])
    prof = _profile(study_file, profile)
    scene_list = scene_list or list(prof.scenes) or ["pipe", "sphere_ghosting"]
    _load_scenes(scene_list)
    _cache_folder()
    limits = {}
    for g in gates:
        m, eq, v = g.partition("=")
        if not eq or m not in AB_METRICS:
            _fail(f"--max-worse {g!r}: expected METRIC=THRESHOLD with METRIC in {', '.join(AB_METRICS)}")
        try:
            limits[m] = float(v)
        except ValueError:
            _fail(f"--max-worse {g!r}: threshold {v!r} is not a number")
        if not math.isfinite(limits[m]) or limits[m] < 0:
            _fail(f"--max-worse {g!r}: the threshold must be a finite number >= 0 (how much worse B may be)")
    pairs = [(None, ca, cb)]
    if render_scale:
        from study.config.techniques import at_scales, upsamples
        if not (upsamples(ca) or upsamples(cb)):
            _fail(f"--render-scale: neither {ca.label!r} nor {cb.label!r} upsamples (taa_impl.upscale)")
        pairs = []
        for sc in render_scale:
            xa, xb = (at_scales(c, [sc])[0] for c in (ca, cb))
            pairs.append((sc, xa, xb))
    any_failed = False
    blocks = []
    for sc, xa, xb in pairs:
        failed, block = _ab_pair(xa, xb, scene_list, prof, video, as_json, limits, sc,
                                 _executor(workers, threads, scheduler), deadline)
        any_failed |= bool(failed)
        blocks.append(block)
    if as_json:
        click.echo(_strict_json(blocks[0] if len(blocks) == 1 else
                                {"render_scales": [p[0] for p in pairs], "results": blocks}))
    if any_failed:
        sys.exit(1)


def _ab_pair(ca, cb, scene_list, prof, video, as_json, limits, scale, executor, deadline=None):
    """One A/B comparison, printed unless `as_json`: (the failed gates, its JSON object)."""
    from study.commands.ab import compare
    from study.commands.common import _stopped
    from study.engine.runner import Study
    from study.engine.stopping import StudyStopped
    from study.engine.tasks import TaskError
    try:
        res = compare(ca, cb, scene_list, prof, progress=not as_json, video=video,
                      study=Study(prof, progress=not as_json, executor=executor, deadline=deadline))
    except TaskError as exc:
        _fail(str(exc))
    except StudyStopped as exc:
        _stopped(exc)
    # a gate with no finite pair to judge fails: it cannot say B is within the threshold
    failed = {m: res.worse_by(m) for m, lim in limits.items() if not res.worse_by(m) <= lim}
    block = {**res.as_dict(), "gates": limits, "failed": failed}
    if scale is not None:
        block["render_scale"] = scale
    if not as_json:
        at = "" if scale is None else f"   at render scale {scale:g}"
        click.echo(f"B = {res.b}  vs  A = {res.a}{at}   (differences B - A, mean [95 % bootstrap CI], n pairs)")
        for scene, per in list(res.per_scene.items()) + [("OVERALL", res.overall)]:
            cells = []
            for m, v in per.items():
                ci = f"[{v['ci'][0]:+.3g}, {v['ci'][1]:+.3g}]" if v["ci"] else "[no interval: one pair]"
                if v.get("interval") == "reference":
                    ci = ci[:-1] + ", reference]"
                if m == "jod" and v["n"] == 0:
                    continue
                mean = "–" if v["mean"] is None else f"{v['mean']:+.4g}"
                cells.append(f"{m} {mean} {ci} n={v['n']}")
            click.echo(f"  {scene:18s} " + "; ".join(cells))
        click.echo(f"  cost: A {res.ms['a']:.2f} ms, B {res.ms['b']:.2f} ms per frame ({res.ms['diff']:+.2f} ms)")
        click.echo(f"  {res.recomputed_line()}")
        for m, w in failed.items():
            click.echo(f"  GATE FAILED: B is worse than A on {m} by {w:.4g} (> {limits[m]})" if math.isfinite(w)
                       else f"  GATE FAILED: {m} has no finite pair to judge")
    return failed, block
