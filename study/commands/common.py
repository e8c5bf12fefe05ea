"""What the `taa-study` commands share: the command group, failing with exit status 2, and the
options and helpers of the study commands."""
from __future__ import annotations

import os
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import click


def _fail(msg: str) -> None:
    click.echo(f"error: {msg}", err=True)
    sys.exit(2)


def _writable_folder(path, what: str) -> Path:
    """`path` as a folder this process can write in (made if missing), or exit 2 saying why."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        _fail(f"{what} {path}: exists and is not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".taa-write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        _fail(f"{what} {path}: cannot write there ({exc.strerror or exc})")
    return path


def _cache_folder() -> Path:
    """The study cache (TAA_STUDY_CACHE or ./.cache/taa-study), checked writable."""
    from references import default_cache_dir
    return _writable_folder(default_cache_dir(), "the cache folder (TAA_STUDY_CACHE)")


def _study_out(path):
    """A study's output folder (study.commands.out_folder.OutFolder): checked, held by this study
    until the command ends (another study's run exits 2 naming it), made only once its report is
    written; exit 2 saying why it cannot be used."""
    from study.commands.out_folder import OutFolder, OutFolderError
    folder = OutFolder(path)
    try:
        folder.__enter__()
    except OutFolderError as exc:
        _fail(str(exc))
    ctx = click.get_current_context(silent=True)
    release = lambda: folder.__exit__(None, None, None)      # noqa: E731
    if ctx is not None:
        ctx.call_on_close(release)        # also when a later _fail exits
    else:
        import atexit
        atexit.register(release)
    return folder


def _write_report(folder, write) -> None:
    """`write(where)` writes the study's report through `folder` (OutFolder.write), or exit 2."""
    from study.commands.out_folder import OutFolderError
    try:
        folder.write(write)
    except OutFolderError as exc:
        _fail(str(exc))


def _scene_and_size(name: str, profile: str, width: int | None, height: int | None):
    from scenes import SceneError, get_scene
    try:
        scene = get_scene(name)
        w, h = scene.resolution(profile)
    except SceneError as exc:
        _fail(str(exc))
    return scene, (w if width is None else width), (h if height is None else height)


class _Group(click.Group):
    """The command group: a command runs with scene warnings shown as one plain line."""

    def invoke(self, ctx):
        import warnings
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            from scenes import SceneWarning
            if issubclass(category, SceneWarning):
                # Python's default shows the warning's source file and line of this project's code:
                # the user wants what is wrong with their scene, not our source
                click.echo(f"warning: {message}", err=True)
            else:
                shown(message, category, filename, lineno, file, line)
        with warnings.catch_warnings():
            warnings.showwarning = show
            return super().invoke(ctx)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
def main():
    """Reference-and-comparison study of temporal anti-aliasing."""


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
    """--workers N: a LocalCluster of N processes (1: in-process); neither it nor --scheduler: the
    default, TAA_STUDY_WORKERS when set, else auto (study.engine.execute)."""
    from study.engine.execute import Executor, cores
    if scheduler and workers:
        _fail("give either --workers N (a local cluster) or --scheduler ADDRESS, not both")
    if scheduler:
        _check_scheduler(scheduler)
        return Executor("scheduler", address=scheduler, threads=threads)
    what = "--workers"
    if workers is None and os.environ.get("TAA_STUDY_WORKERS", "").strip():
        raw = os.environ["TAA_STUDY_WORKERS"].strip()
        if not raw.isdigit() or int(raw) < 1:
            _fail(f"TAA_STUDY_WORKERS={raw!r}: give a whole number of worker processes, 1 or more")
        workers, what = int(raw), "TAA_STUDY_WORKERS"
    if workers is None:
        return Executor.auto(threads)
    if workers > cores():
        # each worker is a process with its own Dr.Jit, EGL context and scene copies: more of them
        # than cores only adds memory and start-up (64 on 2 cores: 4.7 GB and 80 s instead of 7 s)
        click.echo(f"note: {what} {workers}: this machine has {cores()} cores; using {cores()} worker "
                   "processes", err=True)
        workers = cores()
    if workers > 1:
        return Executor("local", workers=workers, threads=threads)
    return Executor("in-process", threads=threads)


CONNECT_TIMEOUT_S = 10.0      # TAA_STUDY_CONNECT_TIMEOUT overrides it
_HANDSHAKE_MAX = 1 << 20      # a Dask handshake is a few hundred bytes


def _check_scheduler(address: str) -> None:
    """Exit 2 unless `address` (tcp://HOST:PORT) answers as a Dask scheduler within the connect
    timeout: the format first, then a TCP connection, the first 8 bytes a Dask server sends (its
    handshake's length: a listener of another kind is refused before distributed reads it and tries
    to allocate what its bytes say), then a Dask client connection. Before any output is made."""
    import socket
    import struct
    import urllib.parse
    raw = os.environ.get("TAA_STUDY_CONNECT_TIMEOUT", "").strip()
    try:
        timeout = float(raw) if raw else CONNECT_TIMEOUT_S
    except ValueError:
        timeout = -1.0
    if not 0 < timeout <= 600:
        _fail(f"TAA_STUDY_CONNECT_TIMEOUT={raw!r}: give seconds, more than 0 and at most 600")
    where = f"--scheduler {address}"
    try:
        url = urllib.parse.urlsplit(address)
        host, port = url.hostname, url.port
    except ValueError as exc:           # a port that is not a number or out of range
        _fail(f"{where}: not an address of the form tcp://HOST:PORT ({exc})")
    if url.scheme != "tcp" or not host or port is None or port == 0 or url.path not in ("", "/") \
            or url.query or url.fragment:
        _fail(f"{where}: not an address of the form tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786)")
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            head = b""
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except socket.timeout:
        _fail(f"{where}: no answer within {timeout:g} s (TAA_STUDY_CONNECT_TIMEOUT); is the scheduler running "
              "and reachable?")
    except OSError as exc:
        _fail(f"{where}: cannot connect ({exc.strerror or exc})")
    if len(head) < 8 or not 0 < struct.unpack("<Q", head)[0] <= _HANDSHAKE_MAX:
        _fail(f"{where}: the listener there is not a Dask scheduler (no Dask handshake)")
    try:
        from distributed import Client
        client = Client(address, timeout=f"{timeout}s")
    except Exception as exc:            # distributed raises OSError, TimeoutError, CommClosedError ...
        _fail(f"{where}: cannot connect as a Dask client ({type(exc).__name__}: {exc})")
    else:
        client.close()


def _strict_json(obj) -> str:
    from study.reporting.encode import strict_json
    return strict_json(obj)


EXECUTION_OPTIONS = [
    click.option("--workers", type=click.IntRange(min=1), default=None,
                 help="Run the tasks on a local Dask cluster of N worker processes (1: in this process; "
                      "at most one per core). Default: one per core, at most 4, for plans of 8 tasks or more "
                      "(TAA_STUDY_WORKERS sets it)."),
    click.option("--threads", type=click.IntRange(min=1), default=None,
                 help="Dr.Jit threads per process (default: the cores shared out among the workers)."),
    click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
                 help="Run the tasks on an existing Dask scheduler (the cache must be on a filesystem every "
                      "worker sees); checked before anything is written, within TAA_STUDY_CONNECT_TIMEOUT "
                      "seconds (default 10)."),
]


def _execution_options(f):
    for opt in reversed(EXECUTION_OPTIONS):
        f = opt(f)
    return f


def _techniques(tech_list, default=()):
    from study.config.techniques import TechniqueConfig, available
    try:
        configs = [TechniqueConfig.parse(t) for t in tech_list] if tech_list else list(default)
    except ValueError as exc:
        _fail(str(exc))
    configs, missing = available(configs)
    if missing:
        from study.config.techniques import resolve_technique
        try:
            resolve_technique(missing[0].name)
        except ValueError as exc:
            _fail(str(exc))
    labels = [c.label for c in configs]
    if len(set(labels)) != len(labels):
        _fail(f"technique labels must be unique, got {labels}")
    from study.config.lod import MIN_LOD_BIAS
    for c in configs:
        try:
            c.make()
        except (TypeError, ValueError, KeyError) as exc:
            _fail(f"technique {c.label!r} ({c.name}, parameters {dict(c.overrides)}): {exc}")
        if c.lod_bias is not None and c.lod_bias < MIN_LOD_BIAS:
            _fail(f"technique {c.label!r}: lod_bias {c.lod_bias:g} is more negative than {MIN_LOD_BIAS:g} "
                  "(a study file may lower its min_lod_bias)")
    return configs


def _profile(study_file, profile):
    from study.config.profile import get_profile
    from study.config.studyfile import StudyFileError
    try:
        return get_profile(study_file or profile)
    except StudyFileError as exc:
        _fail(str(exc))


def _check_render_size(width, height, where: str, processes: int = 1) -> int:
    """Exit 2 unless width x height is a size the raster renders (raster.limits: 8..8192 a side)
    and `processes` processes rendering it fit in the memory available; the need in bytes."""
    from raster.limits import SizeError, check_memory, check_size
    try:
        check_size(width, height, where)
        return check_memory(width, height, where, processes)
    except SizeError as exc:
        _fail(str(exc))


def _study_size(profile, name) -> tuple[int, int]:
    from study.engine.tasks import load_scene
    r = profile.resolution
    return tuple(r) if isinstance(r, (tuple, list)) else load_scene(name).resolution(r)


def _check_study_sizes(profile, names, executor) -> None:
    """Every scene's render size against the memory available to the processes that render at
    once (a local cluster's workers), before the output folder is made."""
    procs = executor.workers if executor.kind in ("local", "auto") else 1
    for name in names:
        w, h = _study_size(profile, name)
        _check_render_size(w, h, f"scene {name} (study {profile.name!r}, resolution {profile.resolution!r})",
                           procs)


def _load_scenes(names):
    from scenes import SceneError
    from study.engine.tasks import load_scene
    try:
        return [load_scene(n) for n in names]
    except SceneError as exc:
        _fail(str(exc))


def _checkout_commit() -> str | None:
    """The commit of this checkout (+modified if tracked files differ from it), for a study's summary
    (`taa-study results` names it); None outside a git checkout."""
    import subprocess
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return head.stdout.strip() + ("+modified" if dirty.returncode == 0 and dirty.stdout.strip() else "")


# The exit status of a study stopped at its --stop-after time (0 finished, 1 a gate failed, 2 bad input).
STOPPED_EXIT = 3


def _stopped(exc) -> None:
    """Exit STOPPED_EXIT after a study stopped at its deadline (study.engine.stopping.StudyStopped)."""
    click.echo(f"taa-study: {exc}", err=True)
    click.echo("taa-study: stopped at the --stop-after time, unfinished: no tables or report written; the "
               "finished tasks are in the cache. To resume, run the same command again (with a new "
               "--stop-after, or without one to finish).", err=True)
    sys.exit(STOPPED_EXIT)


def run_study(profile, names, configs, out_dir, no_agreement, executor, sweep=True, own_columns=True,
              deadline=None):
    """The study end to end: plan and execute its tasks (study.engine.runner), then write its tables, figures
    and report (study.reporting.report.write_study). `profile`: a Profile (study file). `deadline`: no
    task starts after it (study.engine.execute.now()); past it an unfinished study exits STOPPED_EXIT,
    writing nothing. Returns the folder."""
    import time as _time

    from study.commands.out_folder import CANNOT_WRITE, write_failure
    from study.config.profile import SPARSE_SWEEP, sharpen_sweep_configs
    from study.engine.runner import Study
    from study.engine.stopping import StudyStopped
    from study.engine.tasks import TaskError
    from study.reporting.report import write_study

    start = _time.perf_counter()
    _load_scenes(names)
    _check_study_sizes(profile, names, executor)
    folder = _study_out(out_dir or profile.out or f"out/{profile.name}")
    out = folder.path
    _cache_folder()
    study = Study(profile, executor=executor, deadline=deadline)
    sweep_cfg = SPARSE_SWEEP if sweep else ()
    # the sharpen sweep goes with the profile's own columns (not with --techniques)
    sharpen = sharpen_sweep_configs(profile.sharpen_sweep) if own_columns else ()
    try:
        res = study.run(names, configs, agreement=not no_agreement, sweep=sweep_cfg, sharpen=sharpen)
    except TaskError as exc:
        _fail(str(exc))
    except StudyStopped as exc:
        _stopped(exc)
    except OSError as exc:          # a cache file outside any task's record (a full disk, say)
        if exc.errno not in CANNOT_WRITE:
            raise
        _fail(f"the study cache {study.cache.root}: cannot write ({write_failure(exc, study.cache.root)}); "
              "the tasks finished so far stay cached: make room and run the same command again to go on")
    from study.config.profile import thesis_roles
    summary = {**res.stats, "profile": study.profile.name, "scenes": names,
               "techniques": [c.label for c in configs], "roles": thesis_roles(configs),
               "video_metric": study.profile.video.metric,      # 'none': the ghosting tables say why no JOD
               "executor": executor.describe(), "commit": _checkout_commit(),
               "date": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    _write_report(folder, lambda where: write_study(where, res, configs, summary, start))
    from study.engine.store import Store
    Store(study.cache.root).save_hashes()        # the files the report checked
    headline = out / "tables" / "headline.md"
    if headline.exists():       # a study without a static test (a scene group's ghosting alone) has none
        click.echo(headline.read_text())
    else:
        click.echo(f"no static test here, so no headline table: the ghosting tables are in {out / 'tables'}/")
    if (out / "tables" / "reproduction.md").exists():
        click.echo((out / "tables" / "reproduction.md").read_text())
    click.echo(f"runs computed {res.stats['runs_computed']}, cached {res.stats['runs_cached']}; "
               f"metrics computed {res.stats['metrics_computed']}, video {res.stats.get('video_computed', 0)}; "
               f"references rendered "
               f"{res.stats['references_rendered']}; {_time.perf_counter() - start:.1f} s; artefacts in {out}/, "
               f"report {out / 'report.html'}")
    return out


def _builtin_profiles() -> list[str]:
    """The built-in study files' names (study.config.studyfile.builtin_profiles, without its imports)."""
    return sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "config" / "profiles").glob("*.toml"))


PROFILE_OPTION = click.option("--profile", type=click.Choice(_builtin_profiles()), default="quick", show_default=True,
                              help="A built-in study file (study/config/profiles/); STUDY_FILE replaces it.")
