"""The paper's generated part and its PDF, for any paper folder (the repository's paper/ or a copy).

    fill_generated(src, paper_dir) -> {"tables": [stems], "figures": [file names], "body": [...]}
        copies a finished study's LaTeX tables (src/tables/*.tex), its plots and one comparison
        figure with insets per scene (study.reporting.figures, from the thesis protocol's images and
        FLIP maps) into paper_dir/generated/, each table and figure labelled (tab:<stem>,
        fig:<stem>), and writes what main.tex pulls in: generated/summary.tex (the findings in
        sentences), generated/body.tex (the findings and sharpen-test tables, three or four
        scenes' comparison figures, the speed-against-error and convergence plots: what a reader
        needs, set at print size) and generated/appendix.tex (every other table and figure);
    build_pdf(paper_dir) -> paper_dir/main.pdf      (latexmk, or pdflatex twice);
    contents(paper_dir) -> {"pages", "labels", "graphics", "overfull"}   read back from .aux and .log.

Only files the study's manifest lists are taken, so a folder shared with another study adds nothing.
"""
from __future__ import annotations

import csv
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from study.reporting.tables import technique_columns

TABLE_ORDER = ("findings", "sharpen_test", "headline", "reproduction", "history_convergence", "speed_error")
# The body: tables a reader needs first, set at print size; comparison figures of a few scenes
# (the thesis's pipe, lit hairball and flowers, and its ghosting sphere); two plots.
BODY_TABLES = ("findings", "sharpen_test")
BODY_SCENES = ("pipe", "hairball_lit", "flowers", "sphere_ghosting")
BODY_PLOTS = ("speed_error.png", "history_convergence_pipe.png")


class PaperError(RuntimeError):
    """LaTeX failed or is missing; the message says which and quotes the log's error lines."""


def _tex_escape(s: str) -> str:
    return (s.replace("\\", "\\textbackslash{}").replace("&", "\\&").replace("%", "\\%").replace("_", "\\_")
            .replace("#", "\\#").replace("$", "\\$").replace("{", "\\{").replace("}", "\\}"))


def _label(stem: str) -> str:
    return re.sub(r"[^A-Za-z0-9:._-]+", "-", stem)


def _labelled_table(tex: str, stem: str) -> str:
    """The table with \\label{tab:stem} after its caption (labels must follow the caption)."""
    if "\\end{table}" not in tex:
        return tex
    head, _, tail = tex.rpartition("\\end{table}")
    return f"{head}\\label{{tab:{_label(stem)}}}\n\\end{{table}}{tail}"


def _comparison(src: Path, listed: dict, stem: str, scene: str) -> bytes | None:
    """The comparison figure of one scene's static protocol `stem`, or None if its files are missing."""
    from PIL import Image

    from references.exr import read_exr

    from study.reporting.figures import comparison_figure
    ref_rel = f"images/{stem}_{scene}_reference.png"
    if ref_rel not in listed:
        return None
    prefix = f"images/{stem}_{scene}_"
    images, errors = {}, {}
    csv_path = src / "tables" / f"{stem}_{scene}.csv"
    labels = technique_columns(next(csv.reader([csv_path.read_text().splitlines()[0]]))) if csv_path.exists() else []
    from study.reporting.encode import slug
    for label in labels:
        rel = f"{prefix}{slug(label)}.png"
        exr = f"maps/{stem}_{scene}_{slug(label)}.exr"
        if rel not in listed:
            continue
        images[label] = np.asarray(Image.open(src / rel).convert("RGB"))
        if exr in listed:
            errors[label] = read_exr(src / exr)[1]["flip_ldr"]
    if not images:
        return None
    reference = np.asarray(Image.open(src / ref_rel).convert("RGB"))
    return comparison_figure(images, reference, errors)


def fill_generated(src: Path, paper_dir: Path, comparison_stem: str = "static") -> dict:
    """Replace paper_dir/generated/ with the study in `src` (see the module docstring)."""
    from provenance.files import write_bytes_atomic, write_text_atomic
    src, paper_dir = Path(src), Path(paper_dir)
    listed = json.loads((src / "manifest.json").read_text())["artefacts"]
    gen = paper_dir / "generated"
    if gen.exists():
        shutil.rmtree(gen)
    body, appendix = [], []
    tables = sorted((rel for rel in listed if rel.startswith("tables/") and rel.endswith(".tex")
                     and Path(rel).stem != "findings_summary"),
                    key=lambda rel: (Path(rel).stem not in TABLE_ORDER,
                                     TABLE_ORDER.index(Path(rel).stem) if Path(rel).stem in TABLE_ORDER else 0,
                                     Path(rel).stem))
    for rel in tables:
        stem = Path(rel).stem
        write_text_atomic(gen / "tables" / f"{stem}.tex", _labelled_table((src / rel).read_text(), stem))
        (body if stem in BODY_TABLES else appendix).append(f"\\input{{generated/tables/{stem}}}")
    figures = []
    from study.reporting.report_folder import static_scenes
    for scene in static_scenes(listed):
        png = _comparison(src, listed, comparison_stem, scene)
        if png is not None:
            figures.append((f"comparison_{scene}.png", png,
                            f"{scene}: the reference and each technique ({comparison_stem} protocol), with "
                            "magnified insets where the techniques' FLIP errors differ most.", 1.0))
    for rel in sorted(rel for rel in listed if rel.startswith("plots/") and rel.endswith(".png")):
        figures.append((Path(rel).name, (src / rel).read_bytes(), Path(rel).stem.replace("_", " "), 0.7))
    in_body = {f"comparison_{s}.png" for s in BODY_SCENES} | set(BODY_PLOTS)
    for name, data, caption, width in figures:
        write_bytes_atomic(gen / "figures" / name, data)
        stem = Path(name).stem
        (body if name in in_body else appendix).append(
            f"\\begin{{figure}}[H]\\centering\\includegraphics[width={width}\\linewidth]"
            f"{{generated/figures/{name}}}\\caption{{{_tex_escape(caption)}}}"
            f"\\label{{fig:{_label(stem)}}}\\end{{figure}}")
    summary = (src / "tables/findings_summary.tex").read_text() if "tables/findings_summary.tex" in listed else \
        "This study judged none of the thesis's scenes, so it adjudicates none of its claims.\n"
    write_text_atomic(gen / "summary.tex", summary)
    head = "% generated by taa-study paper\n"
    write_text_atomic(gen / "body.tex", head + "\n".join(body) + "\n")
    write_text_atomic(gen / "appendix.tex", head + "\n\\clearpage\n".join(appendix) + "\n")
    write_text_atomic(gen / "results.tex", head + "\\input{generated/body}\n\\clearpage\n\\input{generated/appendix}\n")
    body_stems = [Path(rel).stem for rel in tables if Path(rel).stem in BODY_TABLES] + \
        [f[0] for f in figures if f[0] in in_body]
    return {"tables": [Path(rel).stem for rel in tables], "figures": [f[0] for f in figures], "body": body_stems}


def build_pdf(paper_dir: Path, timeout: float = 600) -> Path:
    """Compile paper_dir/main.tex; PaperError with the log's error lines when it fails."""
    paper_dir = Path(paper_dir)
    latexmk, pdflatex = shutil.which("latexmk"), shutil.which("pdflatex")
    if pdflatex is None:
        raise PaperError("no LaTeX engine found: run `make paper` (it installs latexmk and TeX Live from Debian) "
                         "or `apt-get install latexmk texlive-latex-recommended texlive-latex-extra "
                         "texlive-fonts-recommended`")
    run = lambda cmd: subprocess.run(cmd, cwd=paper_dir, capture_output=True, text=True,   # noqa: E731
                                     timeout=timeout, errors="replace")
    flags = ["-interaction=nonstopmode", "-halt-on-error", "-file-line-error"]
    if latexmk:
        results = [run([latexmk, "-pdf", "-silent", f"-pdflatex=pdflatex {' '.join(flags)} %O %S", "main.tex"])]
    else:   # twice, so that references and float lists settle
        results = [run([pdflatex, *flags, "main.tex"]) for _ in range(2)]
    bad = [r for r in results if r.returncode != 0]
    if bad:
        log = paper_dir / "main.log"
        text = log.read_text(errors="replace") if log.exists() else bad[0].stdout
        errors = [ln for ln in text.splitlines() if ln.startswith("!") or ":error:" in ln or re.match(r"^\S+:\d+: ", ln)]
        raise PaperError(f"LaTeX failed on {paper_dir / 'main.tex'}: " + " | ".join(errors[:8] or [text[-1500:]]))
    return paper_dir / "main.pdf"


def contents(paper_dir: Path) -> dict:
    """What the last build holds: page count, labels (from main.aux), graphics files read,
    overfull boxes and each table's natural width over the line width, in order (from main.log)."""
    paper_dir = Path(paper_dir)
    aux = (paper_dir / "main.aux").read_text(errors="replace")
    log = (paper_dir / "main.log").read_text(errors="replace")
    pages = re.search(r"\\gdef\s*\\@abspage@last\{(\d+)\}", aux)
    if pages is None:
        m = re.search(r"Output written on \S+ \((\d+) pages?", log)
        pages = m
    appendix = re.search(r"\\newlabel\{sec:appendix\}\{\{[^}]*\}\{(\d+)\}", aux)
    body_log = log.split("taa-appendix-start")[0]
    return {"pages": int(pages.group(1)) if pages else None,
            # the body: the pages before the appendix, and its tables' natural widths over the line's
            "body_pages": int(appendix.group(1)) - 1 if appendix else None,
            "body_table_widths": [float(w) / float(lw) for w, lw in
                                  re.findall(r"taa-table: natural width ([\d.]+)pt \(line width ([\d.]+)pt\)", body_log)],
            "labels": re.findall(r"\\newlabel\{([^}]*)\}", aux),
            "graphics": sorted(set(re.findall(r"<(generated/figures/[^>,]+?\.png)", log.replace("\n", "")))),
            "overfull": len(re.findall(r"^Overfull \\hbox", log, re.M)),
            "table_widths": [float(w) / float(lw) for w, lw in
                             re.findall(r"taa-table: natural width ([\d.]+)pt \(line width ([\d.]+)pt\)", log)]}


__all__ = ["fill_generated", "build_pdf", "contents", "PaperError"]
