"""The `paper` command: a study's tables and figures into paper/generated/ and paper/main.pdf,
from the thesis study's finished folder where there is one, else the quick study run make-style
(study.reporting.source)."""
from __future__ import annotations

import click

from study.commands.common import (PROFILE_OPTION, _execution_options, _executor, _fail, _profile, _scene_list,
                                   _techniques, main, run_study)
from study.commands.study_commands import PAPER_DIR


@main.command()
@click.argument("study_file", required=False, type=click.Path(dir_okay=False))
@PROFILE_OPTION
@click.option("--scenes", "scene_list", default=None, callback=_scene_list,
              help="Comma-separated scenes (default: the study file's, or every built-in).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="The study's output folder (default: the study file's, or out/<name>).")
@click.option("--source", type=click.Choice(["auto", "thesis", "quick"]), default=None,
              help="Without STUDY_FILE or --profile: 'auto' (the default) = the thesis study's finished folder "
                   "(out/thesis, 1600x900) where there is one, read as it is, else the quick study, run "
                   "make-style; 'thesis' or 'quick' forces one.")
@click.option("--no-pdf", is_flag=True, help="Only regenerate paper/generated/, do not run LaTeX.")
@_execution_options
@click.pass_context
def paper(ctx, study_file, profile, scene_list, out_dir, no_pdf, workers, threads, scheduler, source):
    """Regenerate the study, copy its tables and figures into paper/generated/, build the PDF."""
    from scenes import builtin_names
    from study.reporting import paper_pdf
    from study.reporting.source import SourceError, choose

    chose_study = (study_file is not None or out_dir is not None or scene_list
                   or ctx.get_parameter_source("profile") != click.core.ParameterSource.DEFAULT)
    if chose_study and source is not None:
        _fail(f"give --source {source} or STUDY_FILE/--profile/--out/--scenes, not both")
    src = None
    if not chose_study:
        try:
            chosen = choose(source or "auto")
        except SourceError as exc:
            _fail(str(exc))
        click.echo(f"taa-study paper: from {chosen.why}")
        if chosen.profile == "thesis":      # finished: read as it is (running it again costs hours)
            src = chosen.folder
        profile = chosen.profile
    if src is None:
        prof = _profile(study_file, profile)
        src = run_study(prof, scene_list or list(prof.scenes) or builtin_names(), _techniques((), prof.techniques),
                        out_dir, not prof.agreement, _executor(workers, threads, scheduler), sweep=prof.sweep)
    root = PAPER_DIR
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
