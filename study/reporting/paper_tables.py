"""The study's LaTeX tables set for the paper's page: never shrunk, split or turned instead.

A study writes each table as one booktabs tabular (study.reporting.tables.Table.latex), one column
per technique, which at thirteen techniques is twice the width of an A4 page. The paper sets every
table at 8 pt (\\footnotesize) as a longtable (it breaks across pages), and where the table is wider
than the line:

    1. long column headings, and text cells among figures (a technique's label under 'best'), are
       wrapped onto lines no wider than the column's figures;
    2. a table of metric rows by technique columns ('metric' first) is transposed: a row per
       technique, a column per metric (its 'best' and 'vs best' columns become rows);
    3. what is still too wide is split into column groups, each repeating the leading label
       columns (scene, protocol, metric, technique), as tables "(columns 1-5 of 13)".

Widths are estimated from Latin Modern's advance widths (a per-character table, 5 % margin);
tests/test_paper_pdf.py checks the built PDF for text under 6 pt and text beyond the margins.

    parse(tex) -> ParsedTable              the tabular's columns, heading, rows and caption;
    paper_table(tex, label, line_pt) -> str    the longtable(s) for the paper.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

SIZE_PT = 8.0          # \footnotesize in a 10 pt article
TABCOLSEP_PT = 4.0
# A4 with 2 cm margins (paper/main.tex): 210 mm - 40 mm = 170 mm
LINE_PT = 170 / 25.4 * 72.27

# Latin Modern Roman advance widths in em (lmr10's AFM, rounded): the characters the tables use.
_EM = {**{c: 0.5 for c in "0123456789"}, " ": 0.333, ".": 0.278, ",": 0.278, ":": 0.278, ";": 0.278,
       "(": 0.389, ")": 0.389, "[": 0.278, "]": 0.278, "-": 0.333, "+": 0.778, "=": 0.778, "/": 0.5,
       "%": 0.833, "'": 0.278, "|": 0.278, "!": 0.278, "?": 0.472, "*": 0.5, "<": 0.778, ">": 0.778,
       "_": 0.5, "&": 0.778, "#": 0.833, "i": 0.278, "j": 0.306, "l": 0.278, "f": 0.306, "t": 0.389,
       "r": 0.392, "s": 0.394, "c": 0.444, "e": 0.444, "z": 0.444, "a": 0.5, "v": 0.528, "x": 0.528,
       "y": 0.528, "k": 0.528, "b": 0.556, "d": 0.556, "g": 0.5, "h": 0.556, "n": 0.556, "o": 0.5, "p": 0.556,
       "q": 0.528, "u": 0.556, "w": 0.722, "m": 0.833, "I": 0.361, "J": 0.514, "M": 0.917, "W": 1.028,
       "–": 0.5, "−": 0.778, "±": 0.778, "×": 0.778, "∞": 1.0, "ρ": 0.52, "μ": 0.6, "≥": 0.778, "≤": 0.778}
_UPPER = 0.75


def text_width(s: str, size_pt: float = SIZE_PT) -> float:
    """The estimated width (pt) of LaTeX cell text `s` at `size_pt`."""
    s = (s.replace("\\textbackslash{}", "\\").replace("$\\times$", "×").replace("$\\infty$", "∞")
         .replace("$\\geq$", "≥").replace("--", "–"))
    s = re.sub(r"\\([&%_#$])", r"\1", s)
    s = re.sub(r"\\[A-Za-z]+\*?", "", s).replace("{", "").replace("}", "").replace("$", "")
    em = sum(_EM.get(c, _UPPER if c.isupper() else 0.5) for c in s)
    return 1.05 * em * size_pt


@dataclass
class ParsedTable:
    columns: list            # per column: "l", "r", "c" or a width as a fraction of the line
    header: list
    rows: list
    caption: str
    widths: list = field(default_factory=list)    # estimated natural widths (pt), after layout


_CELL_SPLIT = re.compile(r"(?<!\\)&")


def _split_cells(line: str) -> list[str]:
    line = line.strip()
    if line.endswith("\\\\"):
        line = line[:-2].rstrip()
    return [c.strip() for c in _CELL_SPLIT.split(line)] if line else []


def parse(tex: str) -> ParsedTable:
    """The parts of a tabular written by study.reporting.tables.Table.latex; ValueError naming what
    is missing when `tex` is not one."""
    m = re.search(r"\\begin\{tabular\}\{(.*)\}\s*\n", tex)
    if m is None or "\\toprule" not in tex or "\\midrule" not in tex or "\\bottomrule" not in tex:
        raise ValueError("not a booktabs table of study.reporting.tables (no tabular with "
                         "\\toprule, \\midrule and \\bottomrule)")
    columns = [float(p) if p else a for p, a in
               re.findall(r">\{[^}]*\}p\{([\d.]+)\\linewidth\}|([lrc])", m.group(1))]
    head = tex.split("\\toprule", 1)[1].split("\\midrule", 1)[0]
    body = tex.split("\\midrule", 1)[1].split("\\bottomrule", 1)[0]
    header = _split_cells(" ".join(head.split("\n")))
    rows = [_split_cells(ln) for ln in body.split("\n") if ln.strip()]
    cap = tex.split("\\caption{", 1)
    caption = cap[1].split("\\end{table}", 1)[0].rsplit("}", 1)[0].strip() if len(cap) == 2 else ""
    if len(header) != len(columns) or any(len(r) != len(columns) for r in rows):
        raise ValueError(f"a row's cells do not match the table's {len(columns)} columns")
    return ParsedTable(columns, header, rows, caption)


def _wrap(cell: str, width: float) -> list[str]:
    """A heading's words on lines no wider than `width` (a longer word keeps a line of its own)."""
    lines: list[str] = []
    for word in cell.split(" "):
        if lines and text_width(lines[-1] + " " + word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines


_NUMBER = re.compile(r"^[\s$+\-–−]*[\d.]")


def _column_widths(t: ParsedTable, line_pt: float) -> tuple[list[float], list[list[str]], list[list[list[str]]]]:
    """Each column's width (pt, padding included), its heading's lines and each body cell's lines.
    A column of figures is as wide as its widest figure (40 pt at least); a heading or a text cell
    (a technique's label under 'best') wider than that wraps at its spaces. A column of text alone
    wraps beyond 0.28 of the line."""
    widths, heads, cells = [], [], []
    for j, col in enumerate(t.columns):
        column = [r[j] for r in t.rows]
        if isinstance(col, float):
            widths.append(col * line_pt + 2 * TABCOLSEP_PT)
            heads.append([t.header[j]])
            cells.append([[c] for c in column])
            continue
        figures = [text_width(c) for c in column if _NUMBER.match(c)]
        target = max(figures) if figures else min(max(map(text_width, column), default=0.0), 0.28 * line_pt)
        words = [w for c in column + [t.header[j]] for w in c.split(" ")]
        target = max(target, 40.0, max(map(text_width, words), default=0.0))
        lines = [_wrap(c, target) for c in column]
        head = _wrap(t.header[j], target)
        widths.append(max(text_width(ln) for ls in lines + [head] for ln in ls) + 2 * TABCOLSEP_PT)
        heads.append(head)
        cells.append(lines)
    return widths, heads, [[cells[j][i] for j in range(len(t.columns))] for i in range(len(t.rows))]


def transpose(t: ParsedTable) -> ParsedTable:
    """A metric-by-technique table as technique rows by metric columns; its trailing columns
    ('best', '<technique> vs best', '± reference') become rows after the techniques."""
    header = ["technique"] + [r[0] for r in t.rows]
    rows = [[t.header[j]] + [r[j] for r in t.rows] for j in range(1, len(t.header))]
    return ParsedTable(["l"] + ["r"] * len(t.rows), header, rows, t.caption)


def _keys(t: ParsedTable) -> int:
    """How many leading columns label a row (text in every row, not figures): 1 or 2."""
    def texty(j):
        return all(not re.match(r"^[\s$+\-–−]*[\d.]", r[j]) for r in t.rows)
    return 2 if len(t.columns) > 3 and texty(0) and texty(1) and isinstance(t.columns[1], str) else 1


def _groups(widths: list[float], keys: int, line_pt: float) -> list[list[int]]:
    """The other columns in the fewest groups that fit beside the key columns, of even size."""
    rest = list(range(keys, len(widths)))
    room = line_pt - sum(widths[:keys])
    for n in range(1, len(rest) + 1):
        size = math.ceil(len(rest) / n)
        groups = [rest[i:i + size] for i in range(0, len(rest), size)]
        if all(sum(widths[j] for j in g) <= room for g in groups):
            return groups
    return [[j] for j in rest]


def _cell_head(lines: list[str], align: str, pos: str = "b") -> str:
    """A cell of one line as it is, of several as a nested tabular (a heading's bottom-aligned, a
    body cell's top-aligned; no padding)."""
    if len(lines) == 1:
        return lines[0]
    return f"\\begin{{tabular}}[{pos}]{{@{{}}{align}@{{}}}}" + "\\\\".join(lines) + "\\end{tabular}"


def _longtable(t: ParsedTable, cols: list[int], heads: list, lines: list, caption: str,
               label: str | None) -> str:
    spec = "".join(f">{{\\raggedright\\arraybackslash}}p{{{t.columns[j]:.4f}\\linewidth}}"
                   if isinstance(t.columns[j], float) else t.columns[j] for j in cols)
    align = [c if isinstance(c, str) else "l" for c in t.columns]
    head = " & ".join(_cell_head(heads[j], align[j]) for j in cols) + " \\\\"
    n = len(cols)
    lab = f"\\label{{{label}}}" if label else ""
    out = ["{\\footnotesize\\setlength{\\tabcolsep}{4pt}",
           f"\\begin{{longtable}}{{{spec}}}",
           f"\\caption{{{caption}}}{lab}\\\\", "\\toprule", head, "\\midrule", "\\endfirsthead",
           f"\\multicolumn{{{n}}}{{l}}{{\\emph{{(continued)}}}}\\\\", "\\toprule", head, "\\midrule", "\\endhead",
           "\\bottomrule", "\\endlastfoot"]
    out += [" & ".join(_cell_head(r[j], align[j], "t") for j in cols) + " \\\\" for r in lines]
    out += ["\\end{longtable}}"]
    return "\n".join(out)


def paper_table(tex: str, label: str, line_pt: float = LINE_PT) -> tuple[str, dict]:
    """The table `tex` (Table.latex) as the paper sets it (module docstring), and how: {"parts",
    "transposed", "width_pt" (the widest part's estimated width), "line_pt"}."""
    t = parse(tex)
    widths, heads, lines = _column_widths(t, line_pt)
    transposed = False
    fracs = [c for c in t.columns if isinstance(c, float)]
    if fracs and sum(widths) > line_pt:     # wrapped columns are narrowed to the line, not the text
        room = line_pt - sum(w for w, c in zip(widths, t.columns) if not isinstance(c, float)) \
            - 2 * TABCOLSEP_PT * len(fracs)
        k = room / (sum(fracs) * line_pt)
        if 0 < k < 1:
            t.columns = [c * k if isinstance(c, float) else c for c in t.columns]
            widths, heads, lines = _column_widths(t, line_pt)
    if sum(widths) > line_pt and t.header[0] == "metric" and len(t.header) > len(t.rows) + 1:
        t, transposed = transpose(t), True
        widths, heads, lines = _column_widths(t, line_pt)
    if sum(widths) <= line_pt or all(isinstance(c, float) for c in t.columns):
        groups, keys = [list(range(len(widths)))], 0
    else:
        keys = _keys(t)
        groups = _groups(widths, keys, line_pt)
    parts = []
    caption = t.caption
    for i, g in enumerate(groups):
        cols = list(range(keys)) + g
        if len(groups) > 1:
            first, last = g[0] - keys + 1, g[-1] - keys + 1
            span = f"columns {first}--{last} of {len(widths) - keys}"
            cap = f"{caption} ({span})" if i == 0 else \
                f"{caption.split('. ', 1)[0]} ({span}; the note is under the first part)"
        else:
            cap = caption
        parts.append(_longtable(t, cols, heads, lines, cap, label if i == 0 else None))
    t.widths = widths
    width = max(sum(widths[j] for j in list(range(keys)) + g) for g in groups)
    return ("% generated by taa-study paper (study.reporting.paper_tables); do not edit\n"
            + "\n\\bigskip\n".join(parts) + "\n",
            {"parts": len(parts), "transposed": transposed, "width_pt": width, "line_pt": line_pt})


__all__ = ["parse", "paper_table", "transpose", "text_width", "ParsedTable", "LINE_PT", "SIZE_PT"]
