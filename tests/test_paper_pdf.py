"""Comparison figures with insets (study.reporting.figures) on synthetic images, the paper's tables set
for the page (study.reporting.paper_tables), and the paper's PDF (study.reporting.paper_pdf +
paper/main.tex + paper/references.bib) built from a real tiny study's tables and figures where LaTeX is
installed (`make test` and `make paper` install it; a plain pytest run elsewhere skips it with the
reason, `make test` fails instead)."""
import io
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from study.reporting import paper_pdf
from study.reporting.figures import comparison_figure, inset_regions

sys.path.insert(0, str(Path(__file__).parent))
from study_fixtures import run_tiny_study  # noqa: E402

H, W = 54, 96
PAPER = Path(__file__).resolve().parent.parent / "paper"


def _inside(box, x, y) -> bool:
    bx, by, bw, bh = box
    return bx <= x < bx + bw and by <= y < by + bh


def _overlap(a, b) -> bool:
    return a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]


def test_insets_go_where_the_techniques_differ_most():
    a, b = np.zeros((H, W)), np.zeros((H, W))
    a[28:32, 60:64] = 1.0               # only A is wrong here: spread 1
    b[8:11, 10:13] = 0.6                # only B is wrong here: spread 0.6
    a[40:50, 80:90] = b[40:50, 80:90] = 0.9   # both equally wrong (a bigger, stronger blob): spread 0
    regions = inset_regions({"A": a, "B": b}, n=2, size=10)
    assert len(regions) == 2 and all(r[2:] == (10, 10) for r in regions)
    first, second = regions
    assert all(_inside(first, x, y) for x in range(60, 64) for y in range(28, 32))
    assert all(_inside(second, x, y) for x in range(10, 13) for y in range(8, 11))
    assert not any(_inside(r, 85, 45) for r in regions)
    # centred on the blob rather than the first tied window: the blob's centre (61.5, 29.5) is
    # within a pixel of the window's
    assert abs(first[0] + 4.5 - 61.5) <= 1 and abs(first[1] + 4.5 - 29.5) <= 1


def test_one_technique_insets_follow_its_error_and_never_overlap():
    e = np.zeros((H, W))
    e[5, 90] = 3.0
    e[50, 3] = 2.0
    e[30:33, 40:43] = 0.3               # 9 px x 0.3 = 2.7: between the two single pixels
    regions = inset_regions({"only": e}, n=3, size=8)
    assert _inside(regions[0], 90, 5) and _inside(regions[1], 40, 30) and _inside(regions[2], 3, 50)
    many = inset_regions({"only": np.random.default_rng(1).random((H, W))}, n=50, size=20)
    assert 1 <= len(many) <= (W // 20) * (H // 20)
    assert all(0 <= x and 0 <= y and x + 20 <= W and y + 20 <= H for x, y, _, _ in many)
    assert not any(_overlap(p, q) for i, p in enumerate(many) for q in many[i + 1:])


def test_figure_magnifies_the_region_with_the_error():
    yy, xx = np.mgrid[:H, :W]
    ref = np.stack([xx * 2, yy * 3, np.full((H, W), 80)], -1).astype(np.uint8)
    a, b = ref.copy(), ref.copy()
    a[28:32, 60:64] = (255, 0, 255)     # a colour found nowhere else
    ea = np.zeros((H, W))
    ea[28:32, 60:64] = 1.0
    png = comparison_figure({"A": a, "B": b}, ref, {"A": ea, "B": np.zeros((H, W))}, n_insets=2, inset_size=12)
    im = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    magenta = ((im[..., 0] > 230) & (im[..., 1] < 30) & (im[..., 2] > 230)).sum()
    # A column is 320 px: the full frame shows the 16 patch pixels at (320/96)^2 each, the inset at
    # (320/12)^2 each; only an inset on the patch gives this many.
    column = 320
    assert magenta > 0.8 * 16 * (column / 12) ** 2
    assert im.shape[1] == pytest.approx(3 * column, abs=3)
    assert im.shape[0] == pytest.approx(column * (H / W + 2) + 0.3 * column / 1.6, abs=4)


def test_figure_refuses_mismatched_inputs():
    ref = np.zeros((H, W, 3), np.uint8)
    with pytest.raises(ValueError, match="image 'A' is"):
        comparison_figure({"A": np.zeros((H, W + 1, 3), np.uint8)}, ref, {})
    with pytest.raises(ValueError, match="error map 'A' is"):
        comparison_figure({"A": ref}, ref, {"A": np.zeros((H + 1, W))})
    with pytest.raises(ValueError, match="does not fit"):
        inset_regions({"A": np.zeros((H, W))}, size=H + 1)


def _wide_table(n_techniques=13):
    """A static test's table as the study writes it, one column per technique (thirteen: the quick
    profile's), with long labels."""
    from study.reporting.tables import thesis_layout
    labels = [f"Technique {i}, sharpen w=0.{i}" for i in range(n_techniques)]
    rng = np.random.default_rng(3)
    results = {l: {"psnr": 30 + rng.random(), "ssim": rng.random(), "mse": 100 * rng.random(),
                   "flip_ldr": rng.random(), "relmse_hdr": rng.random() / 10} for l in labels}
    unc = {l: {m: 1e-3 for m in results[l]} for l in labels}
    return thesis_layout("Static test: pipe", results, ["mse", "psnr", "ssim", "flip_ldr", "relmse_hdr"],
                         labels[4], "A note.", unc).latex(), labels


def test_a_wide_table_is_transposed_or_split_never_shrunk():
    from study.reporting.paper_tables import LINE_PT, paper_table, parse
    tex, labels = _wide_table()
    t = parse(tex)
    assert t.header[1:-3] == [l.replace("_", "\\_") for l in labels] and len(t.rows) == 5
    out, how = paper_table(tex, "tab:static_pipe")
    # five metrics by thirteen techniques: a row per technique, a column per metric, which fits
    assert how["transposed"] and how["parts"] == 1 and how["width_pt"] <= LINE_PT
    assert "\\resizebox" not in out and "\\tiny" not in out and "\\scalebox" not in out
    assert out.count("\\label{tab:static_pipe}") == 1 and "\\footnotesize" in out
    # the techniques are now the rows (their labels first in a row), the metrics the heading
    body = out.split("\\endlastfoot", 1)[1]
    assert [ln.split(" & ")[0] for ln in body.strip().splitlines()[:13]] == labels
    # too many columns even transposed: split into groups repeating the label column, each fitting
    many = paper_table(tex, "tab:x", line_pt=220.0)
    assert many[1]["parts"] >= 2 and many[1]["width_pt"] <= 220.0
    assert many[0].count("\\begin{longtable}") == many[1]["parts"] and "columns 1--" in many[0]
    # a table of wrapped text columns wider than the line is narrowed to it, its text kept at 8 pt
    wrapped = ("\\begin{table}[t]\n\\footnotesize\n\\begin{tabular}{" + "".join(
        f">{{\\raggedright\\arraybackslash}}p{{{w}\\linewidth}}" for w in (0.5, 0.5, 0.3)) + "}\n\\toprule\n"
        "a & b & c \\\\\n\\midrule\nx & y & z \\\\\n\\bottomrule\n\\end{tabular}\n\\caption{W}\n\\end{table}\n")
    out, how = paper_table(wrapped, "tab:w")
    assert how["parts"] == 1 and how["width_pt"] == pytest.approx(LINE_PT, abs=0.5)
    with pytest.raises(ValueError, match="not a booktabs table"):
        parse("\\begin{tabular}{l}a\\end{tabular}")


# -- the PDF -------------------------------------------------------------------------------------------
def _latex_missing():
    """Why the PDF cannot be built here, or None. Under `make test` (TAA_REQUIRE_LATEX=1, after it
    installed TeX) a missing toolchain fails the test: CI must build the paper, not skip it."""
    import os
    for exe in ("pdflatex", "latexmk"):
        if shutil.which(exe) is None:
            why = f"{exe} is not installed (`make test` and `make paper` install it: scripts/setup_latex.sh)"
            if os.environ.get("TAA_REQUIRE_LATEX") == "1":
                pytest.fail(f"TAA_REQUIRE_LATEX=1 but {why}")
            return why
    return None


SECTIONS = ("Introduction", "Related work", "Method", "Results", "Discussion", "Limitations", "Reproducibility",
            "References")
CITED = {"karis2014", "xu2016", "pedersen2016", "salvi2016", "yang2020", "lottes2009", "jimenez2012", "wang2004",
         "andersson2020", "mantiuk2024", "reinhard2002", "fsr2", "oliveros2018", "li2021", "marin2015",
         "ferrando2018", "mitsuba3", "jakob2022"}
MIN_TEXT_PT = 6.0


def _pdf_text(pdf) -> str:
    from pdfminer.high_level import extract_text
    return re.sub(r"\s+", " ", extract_text(str(pdf)))


@pytest.mark.long(seconds=20)
def test_paper_builds_from_a_tiny_study_with_its_sections_and_no_text_under_6pt(tmp_path, reference_pool):
    why = _latex_missing()
    if why:
        print(f"skipping the PDF build: {why}")
        pytest.skip(why)
    out = run_tiny_study(tmp_path, "noaa", "taa_baseline", pool=reference_pool)
    paper = tmp_path / "paper"
    paper.mkdir()
    for name in ("main.tex", "references.bib"):                # the repository's own paper
        shutil.copy(PAPER / name, paper / name)
    got = paper_pdf.fill_generated(out, paper)
    tables = sorted(p.stem for p in (out / "tables").glob("*.tex"))
    assert sorted(got["tables"]) == sorted(t for t in tables if t != "findings_summary")
    assert got["tables"][:3] == ["findings", "headline", "reproduction"] and got["body"][0] == "findings"
    assert (paper / "generated/summary.tex").read_text() == (out / "tables/findings_summary.tex").read_text()
    assert sorted(f for f in got["figures"] if f.startswith("comparison_")) == \
        ["comparison_tiny_moving.png", "comparison_tiny_still.png"]
    assert set(got["figures"]) >= {p.name for p in (out / "plots").glob("*.png")}
    # the results say where they are from; the reproducibility section names the manifest's hash
    import hashlib
    assert "Profile quick, at 36$\\times$20, 40$\\times$24;" in (paper / "generated/scope.tex").read_text()
    assert hashlib.sha256((out / "manifest.json").read_bytes()).hexdigest() in \
        (paper / "generated/reproducibility.tex").read_text()

    start = time.perf_counter()
    pdf = paper_pdf.build_pdf(paper)
    took = time.perf_counter() - start
    c = paper_pdf.contents(paper)
    sizes = paper_pdf.text_sizes(pdf)
    print(f"paper: {c['pages']} pages ({c['body_pages']} body), {len(got['tables'])} tables, "
          f"{len(got['figures'])} figures, {c['overfull']} overfull boxes, smallest text {sizes['min_pt']:.2f} pt, "
          f"built in {took:.1f} s: {pdf}")
    assert pdf.is_file() and pdf.read_bytes()[:5] == b"%PDF-"
    assert set(c["labels"]) >= {f"tab:{t}" for t in got["tables"]} | {f"fig:{Path(f).stem}" for f in got["figures"]}
    assert c["graphics"] == sorted(f"generated/figures/{f}" for f in got["figures"])
    # a paper: its sections in order, then the appendix; every citation resolved by bibtex
    assert [t for t, _ in c["sections"]][:len(SECTIONS)] == list(SECTIONS), c["sections"]
    text = _pdf_text(pdf)
    assert all(f"{i} {t}" in text for i, t in enumerate(SECTIONS[:-1], start=1)) and "References" in text
    assert c["sections"][len(SECTIONS)][0].startswith("Every table and figure")     # the appendix
    assert c["undefined_citations"] == [] and set(c["bibliography"]) == CITED
    assert 1 <= c["body_pages"] <= 12 and "sec:appendix" in c["labels"]
    # no text under 6 pt on any page (nothing shrunk), and none run past the page's margins
    assert sizes["pages"] == c["pages"] and sizes["min_pt"] >= MIN_TEXT_PT, \
        {p: s for p, s in sizes["sizes"].items() if s < MIN_TEXT_PT}
    assert sizes["outside"] == [] and c["overfull"] == 0
    if shutil.which("pdfinfo"):
        info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
        assert re.search(rf"^Pages:\s+{c['pages']}$", info, re.M) and "(A4)" in info
    if shutil.which("pdftoppm"):          # the first pages as pictures, a test artefact to look at
        subprocess.run(["pdftoppm", "-png", "-r", "60", "-f", "1", "-l", "3", str(pdf), str(tmp_path / "page")],
                       check=True)
        print("pages as PNG:", " ".join(str(p) for p in sorted(tmp_path.glob("page*.png"))))


def test_the_size_check_sees_a_shrunk_table_and_text_past_the_margin(tmp_path):
    """The old template's way with a wide table (\resizebox of a \tiny tabular) reads as text under
    6 pt, and a line run into the margin as text outside it."""
    why = _latex_missing()
    if why:
        pytest.skip(why)
    (tmp_path / "main.tex").write_text(
        "\\documentclass[10pt,a4paper]{article}\n\\usepackage[margin=2cm]{geometry}\\usepackage{graphicx}\n"
        "\\begin{document}\nNormal text.\n\n\\resizebox{\\linewidth}{!}{\\tiny\\begin{tabular}{" + "l" * 30 + "}"
        + " & ".join(["column"] * 30) + " \\\\\\end{tabular}}\n\n\\noindent\\hspace*{18cm}\\mbox{overrun}\n\\end{document}\n")
    s = paper_pdf.text_sizes(paper_pdf.build_pdf(tmp_path))
    assert s["pages"] == 1 and s["min_pt"] < 5.5 and s["sizes"][1] == s["min_pt"]
    assert "".join(t for _, t in s["outside"]) == "overrun"


def test_a_latex_error_is_reported_with_its_line(tmp_path):
    why = _latex_missing()
    if why:
        pytest.skip(why)
    (tmp_path / "main.tex").write_text("\\documentclass{article}\n\\begin{document}\n\\undefinedmacro\n\\end{document}\n")
    with pytest.raises(paper_pdf.PaperError, match="Undefined control sequence"):
        paper_pdf.build_pdf(tmp_path)
