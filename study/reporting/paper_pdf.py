"""The paper's generated part and its PDF, for any paper folder (the repository's paper/ or a copy).

    fill_generated(src, paper_dir) -> {"tables": [stems], "figures": [file names], "body": [...],
                                       "layout": {stem: how the table was set}}
        copies a finished study's LaTeX tables (src/tables/*.tex), set for the page by
        study.reporting.paper_tables (8 pt longtables; too wide ones transposed or split, never
        shrunk), its plots and one comparison figure with insets per scene (study.reporting.figures,
        from the thesis protocol's images and FLIP maps) into paper_dir/generated/, each table and
        figure labelled (tab:<stem>, fig:<stem>), and writes what main.tex pulls in:
        generated/summary.tex (the findings in sentences), generated/scope.tex (the profile,
        resolutions and protocols the results are at), generated/discussion.tex (the measured
        causes), generated/reproducibility.tex (command, commit, the manifest's SHA-256),
        generated/body.tex (the findings and sharpen-test tables, three or four scenes' comparison
        figures, the speed-against-error and convergence plots) and generated/appendix.tex (every
        other table and figure);
    build_pdf(paper_dir) -> paper_dir/main.pdf      (latexmk with bibtex, or pdflatex/bibtex/pdflatex x2);
    contents(paper_dir) -> {"pages", "body_pages", "labels", "sections", "graphics", "overfull",
                            "undefined_citations", "bibliography"}
        read back from .aux and .log;
    text_sizes(pdf) -> {"min_pt", "pages_under", ...}   every character's size and position
        (pdfminer.six, the test extra): the smallest text and any past the page's margins.

Only files the study's manifest lists are taken, so a folder shared with another study adds nothing.
"""
from __future__ import annotations

import csv
import json
import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from study.reporting import paper_sections as sections
from study.reporting.paper_tables import paper_table
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
    layout = {}
    for rel in tables:
        stem = Path(rel).stem
        try:
            tex, layout[stem] = paper_table((src / rel).read_text(), f"tab:{_label(stem)}")
        except ValueError as exc:
            raise PaperError(f"{src / rel}: {exc}") from None
        write_text_atomic(gen / "tables" / f"{stem}.tex", tex)
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
    record = json.loads((src / "tables/findings.json").read_text()) if "tables/findings.json" in listed else None
    summary_info = json.loads((src / "manifest.json").read_text()).get("summary", {})
    write_text_atomic(gen / "scope.tex", head + sections.scope(record, summary_info) + "\n")
    write_text_atomic(gen / "discussion.tex", head + sections.discussion(record) + "\n")
    write_text_atomic(gen / "reproducibility.tex",
                      head + sections.reproducibility(src / "manifest.json", summary_info) + "\n")
    write_text_atomic(gen / "body.tex", head + "\n".join(body) + "\n")
    # the appendix flows: a table or figure follows the last (longtables break across pages)
    write_text_atomic(gen / "appendix.tex", head + "\n\\bigskip\n".join(appendix) + "\n")
    body_stems = [Path(rel).stem for rel in tables if Path(rel).stem in BODY_TABLES] + \
        [f[0] for f in figures if f[0] in in_body]
    return {"tables": [Path(rel).stem for rel in tables], "figures": [f[0] for f in figures], "body": body_stems,
            "layout": layout}


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
    if latexmk:     # latexmk runs bibtex and pdflatex until the references settle
        results = [run([latexmk, "-pdf", "-bibtex", "-silent", f"-pdflatex=pdflatex {' '.join(flags)} %O %S",
                        "main.tex"])]
    else:           # pdflatex, bibtex, then pdflatex twice, so that citations and float lists settle
        results = [run([pdflatex, *flags, "main.tex"])]
        if shutil.which("bibtex") and "\\bibliography{" in (paper_dir / "main.tex").read_text(errors="replace"):
            results.append(run(["bibtex", "main"]))
        results += [run([pdflatex, *flags, "main.tex"]) for _ in range(2)]
    bad = [r for r in results if r.returncode != 0]
    if bad:
        log = paper_dir / "main.log"
        text = log.read_text(errors="replace") if log.exists() else bad[0].stdout
        errors = [ln for ln in text.splitlines() if ln.startswith("!") or ":error:" in ln or re.match(r"^\S+:\d+: ", ln)]
        raise PaperError(f"LaTeX failed on {paper_dir / 'main.tex'}: " + " | ".join(errors[:8] or [text[-1500:]]))
    return paper_dir / "main.pdf"


def contents(paper_dir: Path) -> dict:
    """What the last build holds: page count, the body's pages (before the appendix), labels and
    sections with their pages (from main.aux), graphics files read, overfull boxes, and citations LaTeX could not resolve and the
    entries bibtex listed (from main.log and main.bbl)."""
    paper_dir = Path(paper_dir)
    aux = (paper_dir / "main.aux").read_text(errors="replace")
    log = (paper_dir / "main.log").read_text(errors="replace")
    bbl = paper_dir / "main.bbl"
    pages = re.search(r"\\gdef\s*\\@abspage@last\{(\d+)\}", aux)
    if pages is None:
        pages = re.search(r"Output written on \S+ \((\d+) pages?", log)
    appendix = re.search(r"\\newlabel\{sec:appendix\}\{\{[^}]*\}\{(\d+)\}", aux)
    return {"pages": int(pages.group(1)) if pages else None,
            "body_pages": int(appendix.group(1)) - 1 if appendix else None,
            "labels": re.findall(r"\\newlabel\{([^}]*)\}", aux),
            # the table of contents' sections: (title, page)
            "sections": [(t.strip(), int(p)) for t, p in re.findall(
                r"\\contentsline \{section\}\{(?:\\numberline \{[^}]*\})?([^{}]*)\}\{(\d+)\}", aux)],
            "graphics": sorted(set(re.findall(r"<(generated/figures/[^>,]+?\.png)", log.replace("\n", "")))),
            "overfull": len(re.findall(r"^Overfull \\hbox", log, re.M)),
            "undefined_citations": sorted(set(re.findall(r"Citation `([^']+)' .*undefined", log))),
            "bibliography": re.findall(r"\\bibitem\[[^\]]*\]\{([^}]+)\}",
                                       bbl.read_text(errors="replace").replace("\n", " ")) if bbl.exists() else []}


def text_sizes(pdf: Path, margin_pt: float = 28.35) -> dict:
    """Every character of `pdf` (pdfminer.six): {"min_pt": the smallest text size, "sizes": {page:
    its smallest size}, "outside": [(page, text)] of characters closer than `margin_pt` (1 cm) to
    the page's edge, "pages": the page count}. A size is the glyph's em in the page's units after
    every scaling and rotation (what a \\resizebox or \\tiny shows as)."""
    from pdfminer.high_level import extract_pages
    from pdfminer.layout import LAParams, LTChar

    def chars(obj):
        if isinstance(obj, LTChar):
            yield obj
        elif hasattr(obj, "__iter__"):
            for child in obj:
                yield from chars(child)

    sizes, outside, n = {}, [], 0
    for n, page in enumerate(extract_pages(str(pdf), laparams=LAParams(all_texts=True)), start=1):
        w, h = page.width, page.height
        for ch in chars(page):
            if not ch.get_text().strip():
                continue
            a, b = ch.matrix[0], ch.matrix[1]
            size = ch.width if abs(b) > abs(a) else ch.height     # turned a quarter: the em lies along x
            sizes[n] = min(sizes.get(n, math.inf), size)
            if ch.x0 < margin_pt or ch.x1 > w - margin_pt or ch.y0 < margin_pt * 0.5 or ch.y1 > h - margin_pt * 0.5:
                outside.append((n, ch.get_text()))
    return {"min_pt": min(sizes.values(), default=math.nan), "sizes": sizes, "outside": outside, "pages": n}


__all__ = ["fill_generated", "build_pdf", "contents", "text_sizes", "PaperError"]
