"""docs/results.md and the README's results block, generated from a finished study's folder.

Nothing is typed in: the numbers come from the study's tables/figures.json (every figure with its
reference uncertainty) and tables/findings.json (the thesis's claims adjudicated,
study.reporting.findings), each checked against the sha256 its manifest.json lists, and are
formatted by the study's own table code (study.reporting.tables, study.reporting.findings_text).
The first line names the study: profile, resolution, commit, the manifest's sha256 and date.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from study.reporting.encode import from_strict
from study.reporting import findings_text as FT
from study.reporting.tables import Table, fmt, fmt_u
from study.reporting.thesis import THESIS_COLUMNS

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
FIGURES, FINDINGS, HEADLINE = "tables/figures.json", "tables/findings.json", "tables/headline.md"


class ResultsError(ValueError):
    """A study folder that cannot give the results document, or a README without its markers (one line)."""


@dataclass
class StudyFiles:
    """What the results document reads from a finished study's folder, checked."""
    folder: Path
    summary: dict
    manifest_sha256: str
    date: str                 # when the study finished, 'YYYY-MM-DD HH:MM UTC'
    figures: dict             # tables/figures.json
    record: dict              # tables/findings.json
    headline: str             # tables/headline.md ('' if the study wrote none)


def _checked(folder: Path, artefacts: dict, rel: str) -> bytes:
    """A file the manifest lists, with the sha256 it lists, or ResultsError."""
    path = folder / rel
    entry = artefacts.get(rel)
    if not isinstance(entry, dict) or not isinstance(entry.get("sha256"), str):
        raise ResultsError(f"{folder}: its manifest.json lists no {rel}: not a finished study; run `taa-study run`")
    if not path.is_file():
        raise ResultsError(f"{path}: missing, though the study's manifest.json lists it; run the study again")
    raw = path.read_bytes()
    got = hashlib.sha256(raw).hexdigest()
    if got != entry["sha256"]:
        raise ResultsError(f"{path}: changed since the study wrote it (sha256 {got[:12]}…, its manifest.json "
                           f"lists {entry['sha256'][:12]}…); run the study again")
    return raw


def _json(raw: bytes, path: Path, keys: dict) -> dict:
    try:
        doc = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{path}: not JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise ResultsError(f"{path}: expected a JSON object, got {type(doc).__name__}")
    for k, kind in keys.items():
        if not isinstance(doc.get(k), kind):
            raise ResultsError(f"{path}: field {k!r} missing or not a {kind.__name__}")
    return doc


def _date(summary: dict, manifest: Path) -> str:
    """The study's date: the one it recorded (UTC), else its manifest's modification time."""
    when = None
    if isinstance(summary.get("date"), str):
        try:
            when = datetime.fromisoformat(summary["date"])
        except ValueError:
            when = None
    if when is None:
        when = datetime.fromtimestamp(manifest.stat().st_mtime, timezone.utc)
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    return when.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def load(folder) -> StudyFiles:
    """The files of a finished study (`taa-study run`'s output folder), each checked against the
    sha256 its manifest lists. ResultsError (one line) for a missing folder, one no study wrote,
    or a file changed since."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ResultsError(f"{folder}: no such folder (a study's output folder; `taa-study run` writes out/quick)")
    mpath = folder / "manifest.json"
    if not mpath.is_file():
        raise ResultsError(f"{folder}: not a study's output folder (no manifest.json); `taa-study run` writes one")
    mraw = mpath.read_bytes()
    manifest = _json(mraw, mpath, {"artefacts": dict, "summary": dict})
    arts = manifest["artefacts"]
    figures = from_strict(_json(_checked(folder, arts, FIGURES), folder / FIGURES, {"tests": list}))   # "inf": ∞
    record = _json(_checked(folder, arts, FINDINGS), folder / FINDINGS, {"claims": list, "protocols": list})
    headline = _checked(folder, arts, HEADLINE).decode() if HEADLINE in arts else ""
    for i, c in enumerate(record["claims"]):
        need = ("id", "claim", "thesis", "unit", "verdict", "effect")
        if not isinstance(c, dict) or any(k not in c for k in need) or not isinstance(c["effect"], dict):
            raise ResultsError(f"{folder / FINDINGS}: claims[{i}] is not a claim (fields {', '.join(need)})")
    return StudyFiles(folder, manifest["summary"], hashlib.sha256(mraw).hexdigest(), _date(manifest["summary"], mpath),
                      figures, record, headline)


def roles(study: StudyFiles) -> dict:
    """Thesis column -> the study's label for it: as the study recorded them, else the columns the
    study has under the thesis's own names (the built-in profiles' labels)."""
    got = study.summary.get("roles")
    if isinstance(got, dict) and all(isinstance(v, str) for v in got.values()):
        return {c: got[c] for c in THESIS_COLUMNS if c in got}
    labels = set(study.summary.get("techniques") or [])
    return {c: c for c in THESIS_COLUMNS if c in labels}


def resolutions(study: StudyFiles) -> list[str]:
    return sorted({f"{t.get('width')}x{t.get('height')}" for t in study.figures["tests"]
                   if isinstance(t, dict) and t.get("protocol") == "static"})


def provenance(study: StudyFiles) -> str:
    """The study a results text comes from, in one line."""
    from study.reporting.source import study_line
    return (f"Generated by `taa-study results` from "
            f"{study_line(study.summary, resolutions(study), study.manifest_sha256, study.date)}. "
            "Do not edit: run the command again.")


def _figure(test: dict, label: str, n: int, where: str):
    """(PSNR, its uncertainty) of `label` in a static test read at history n: the checkpoint n,
    or the single judged frame of a technique without history (study.engine.results.view)."""
    try:
        frames = {int(f): v for f, v in test["techniques"][label]["frames"].items()}
        f = n if n in frames else max(frames)
        v = frames[f]["figures"]["psnr"]
        u = (frames[f].get("uncertainty") or {}).get("psnr")
    except (KeyError, TypeError, ValueError, AttributeError):
        raise ResultsError(f"{FIGURES}: {where}, technique {label!r}: no PSNR at a frame") from None
    for name, x in (("psnr", v), ("its uncertainty", u)):
        if x is None and name != "psnr":
            continue
        if isinstance(x, bool) or not isinstance(x, (int, float)) or math.isnan(x) or x == -math.inf \
                or (name != "psnr" and (x < 0 or math.isinf(x))):
            raise ResultsError(f"{FIGURES}: {where}, technique {label!r}, frame {f}: {name} is {x!r}, "
                               "not a figure")
    return float(v), (None if u is None else float(u))


def thesis_table(study: StudyFiles, first_view_only: bool = False) -> Table | None:
    """The static test's PSNR ± reference under the thesis's five columns, per scene and protocol
    (the headline's rows; None where the study has none of the columns); `first_view_only`: the
    thesis's own protocol alone (the README's short form)."""
    from study.config.profile import view_history
    cols = roles(study)
    if not cols:
        return None
    views = []
    for label in study.record["protocols"]:
        try:
            views.append((label, view_history(label)))
        except (ValueError, TypeError):
            raise ResultsError(f"{FINDINGS}: protocol {label!r} is not a static view's label") from None
    rows = []
    for i, t in enumerate(study.figures["tests"]):
        if not isinstance(t, dict) or t.get("protocol") != "static":
            continue
        if not isinstance(t.get("techniques"), dict):
            raise ResultsError(f"{FIGURES}: tests[{i}] has no techniques")
        for vlabel, n in views[:1] if first_view_only else views:
            cells = []
            for c in THESIS_COLUMNS:
                if c not in cols:
                    continue
                if cols[c] not in t["techniques"]:
                    cells.append("–")
                    continue
                v, u = _figure(t, cols[c], n, f"tests[{i}] ({t.get('scene')}, {vlabel})")
                cells.append(fmt("psnr", v, u) + ("" if u is None else f" ± {fmt_u(u)}"))
            rows.append([str(t.get("scene")), vlabel] + cells)
    header = ["scene", "protocol"] + [c if cols[c] == c else f"{c} ({cols[c]})" for c in THESIS_COLUMNS if c in cols]
    return Table("Static test, PSNR (dB) ± reference, the thesis's five columns", header, rows,
                 "PSNR of each technique's 8-bit display image against the path-traced reference, ± that "
                 "reference's uncertainty (about 2 standard deviations), each figure printed to it.")


def verdict_table(record: dict) -> Table:
    """Per claim of the thesis: its figure, ours and the verdict (study.reporting.findings)."""
    rows = [[c["claim"], c["thesis"], FT.ours(c) + ("" if FT.ours(c) == "–" else " " + c["unit"].split(",")[0]),
             c["verdict"]] for c in record["claims"]]
    return Table(f"The thesis's claims, adjudicated ({', '.join(record.get('resolutions') or []) or '–'})",
                 ["claim", "thesis", "ours", "verdict"], rows,
                 "Ours: this study's mean difference over its cases (scene and protocol), and their range. A case "
                 "is reproduced when its whole interval lies on the thesis's side of zero.")


def results_markdown(study: StudyFiles, why: str | None = None) -> str:
    """The whole of docs/results.md; its first line is provenance(study), then `why` this study
    (study.reporting.source.choose) where given."""
    parts = [provenance(study), ""] + ([f"Source: {why}.", ""] if why else []) + ["# Results", "",
             "The figures of one study, as its output folder holds them: tables/figures.json (every figure with "
             "its reference uncertainty) and tables/findings.json (the thesis's claims adjudicated). The study's "
             "report.html has every table, image and error map.", ""]
    t = thesis_table(study)
    parts += ["## The thesis's columns", "", t.markdown() if t else "This study ran none of the thesis's columns.\n"]
    parts += ["## The thesis's claims", "", verdict_table(study.record).markdown(), "### In words", ""]
    parts += [f"- {s}" for s in FT.summary(study.record)] + [""]
    if study.headline:
        parts += ["## Every technique", "", study.headline.rstrip("\n").replace("### ", "### The headline: ", 1), ""]
    return "\n".join(parts).rstrip("\n") + "\n"


def readme_block(study: StudyFiles, doc_link: str) -> str:
    """The README's results block (the lines between its markers): the thesis's protocol and the
    verdicts; the converged control and every other technique are the document's."""
    t = thesis_table(study, first_view_only=True)
    return "\n".join([provenance(study).replace("Do not edit: run the command again.",
                                                f"The whole of it: [{doc_link}]({doc_link})."), "",
                      t.markdown() if t else "This study ran none of the thesis's columns.\n",
                      verdict_table(study.record).markdown()]).rstrip("\n") + "\n"


def replace_block(text: str, block: str, name: str = "README.md") -> str:
    """`text` with the lines between its BEGIN and END marker lines replaced by `block`; every
    other byte kept. ResultsError unless each marker is there once, BEGIN first."""
    lines = text.splitlines(keepends=True)
    at = {m: [i for i, line in enumerate(lines) if line.strip() == m] for m in (BEGIN, END)}
    if len(at[BEGIN]) != 1 or len(at[END]) != 1 or at[BEGIN][0] > at[END][0]:
        raise ResultsError(f"{name}: needs one line {BEGIN} and, after it, one line {END} (found "
                           f"{len(at[BEGIN])} and {len(at[END])}); add them where the results go, or give "
                           "--readme PATH or --no-readme")
    b, e = at[BEGIN][0], at[END][0]
    nl = "\r\n" if lines[b].endswith("\r\n") else "\n"
    return "".join(lines[:b + 1]) + block.replace("\n", nl) + "".join(lines[e:])


def write(folder, doc, readme=None, why: str | None = None) -> dict:
    """docs/results.md (`doc`) from the study in `folder`, and the block of `readme` (None: no README);
    `why`: why this study (a sentence the document states under its first line).
    Everything is read and checked before anything is written; each file is written whole (a temporary
    name, then a rename). Returns {'doc': path, 'readme': path or None, 'study': StudyFiles}."""
    from provenance.files import write_text_atomic
    study = load(folder)
    doc = Path(doc)
    text = results_markdown(study, why)
    new_readme = None
    if readme is not None:
        readme = Path(readme)
        if not readme.is_file():
            raise ResultsError(f"{readme}: no such file (give --readme PATH or --no-readme)")
        link = os.path.relpath(doc.resolve(), readme.resolve().parent).replace(os.sep, "/")
        try:
            old = readme.read_bytes().decode()
        except UnicodeDecodeError as exc:
            raise ResultsError(f"{readme}: not UTF-8 text ({exc})") from None
        new_readme = replace_block(old, readme_block(study, link), str(readme))
    if doc.exists() and not doc.is_file():
        raise ResultsError(f"{doc}: exists and is not a file")
    try:
        write_text_atomic(doc, text)
        if new_readme is not None:
            write_text_atomic(readme, new_readme)
    except OSError as exc:
        raise ResultsError(f"cannot write {exc.filename or doc}: {exc.strerror or exc}") from None
    return {"doc": doc, "readme": readme, "study": study}
