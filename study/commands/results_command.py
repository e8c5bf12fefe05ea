"""The `results` command: docs/results.md and the README's results block from a finished study
(study.reporting.results_doc): the thesis study at its own scale where a finished one exists, else
the quick study (study.reporting.source)."""
from __future__ import annotations

import click

from study.commands.common import _fail, main


@main.command()
@click.option("--source", type=click.Choice(["auto", "thesis", "quick"]), default="auto", show_default=True,
              help="Which study: 'auto' = the thesis profile's (out/thesis, 1600x900) where it holds a finished "
                   "study, else the quick profile's (out/quick, 320x180); 'thesis' or 'quick' forces one.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="A study's output folder (what `taa-study run` wrote), instead of --source's.")
@click.option("--doc", "doc", type=click.Path(dir_okay=False), default="docs/results.md", show_default=True,
              help="The results document to write.")
@click.option("--readme", type=click.Path(dir_okay=False), default=None,
              help="The README whose lines between <!-- results:begin --> and <!-- results:end --> get the "
                   "short results table (default: README.md).")
@click.option("--no-readme", is_flag=True, help="Write the results document only.")
def results(source, out_dir, doc, readme, no_readme):
    """Write the results document from a finished study's figures and findings (nothing typed in),
    and its short table into the README between its results markers."""
    from study.reporting.results_doc import ResultsError, write
    from study.reporting.source import SourceError, choose
    if readme is not None and no_readme:
        _fail("give --readme PATH or --no-readme, not both")
    if out_dir is not None and source != "auto":
        _fail(f"give --out FOLDER or --source {source}, not both")
    why = None
    if out_dir is None:
        try:
            chosen = choose(source)
        except SourceError as exc:
            _fail(str(exc))
        out_dir, why = chosen.folder, chosen.why
    try:
        got = write(out_dir, doc, None if no_readme else (readme or "README.md"), why)
    except ResultsError as exc:
        _fail(f"{exc}; the source: {why}" if why else str(exc))
    click.echo(f"wrote {got['doc']}" + (f" and the results block of {got['readme']}" if got["readme"] else "")
               + f" from {out_dir}" + (f": {why}" if why else ""))
