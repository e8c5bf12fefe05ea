"""The paper's generated paragraphs (paper/main.tex \\input's them from generated/): the scope of
the results, the discussion of the measured causes and the reproducibility statement, each from a
study's findings record (study.reporting.findings, tables/findings.json) and manifest alone.

    scope(record, summary) -> str             the Results section's first line: the study it comes from
                                              (profile, resolutions, commit, date), its protocols, scenes
                                              and techniques;
    discussion(record) -> str                 each claim's measured cause (its factor, its verdict
                                              against the thesis's ground truth, the resolution)
                                              and the study's factors, in sentences;
    reproducibility(manifest, summary) -> str the command, the commit, the manifest's SHA-256.
"""
from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

from study.reporting import findings_text

ROOT = Path(__file__).resolve().parents[2]      # the checkout (its git commit, when it has one)


def esc(s: str) -> str:
    """Plain text as LaTeX (the characters main.tex does not declare, escaped)."""
    s = (s.replace("\\", "\\textbackslash{}").replace("&", "\\&").replace("%", "\\%").replace("_", "\\_")
         .replace("#", "\\#").replace("$", "\\$").replace("{", "\\{").replace("}", "\\}")
         .replace("~", "\\textasciitilde{}").replace("^", "\\textasciicircum{}"))
    return s.replace("×", "$\\times$").replace("−", "$-$")


def _res(r: str) -> str:
    return r.replace("x", "×")


def scope(record: dict | None, summary: dict) -> str:
    """The line that opens the Results: which study (profile, resolutions, commit, date; the thesis
    study at its scale where `taa-study paper` found one, study.reporting.source), its protocols,
    scenes, techniques."""
    profile = summary.get("profile") or "a study file's"
    scenes = [Path(s).stem for s in summary.get("scenes", [])]
    techniques = summary.get("techniques", [])
    if record is None:
        return esc(f"Profile {profile}: this study has no findings record (tables/findings.json).")
    from study.reporting.source import study_line
    res = ", ".join(_res(r) for r in record["resolutions"]) or "no static test"
    line = (f"From {study_line(summary, [_res(r) for r in record['resolutions']])}. "
            f"Profile {profile}, at {res}; static protocols: {', '.join(record['protocols']) or 'none'}; "
            f"ghosting protocols: {', '.join(record['ghosting_protocols']) or 'none'}; "
            f"{len(scenes)} scene{'s' * (len(scenes) != 1)}, {len(techniques)} technique"
            f"{'s' * (len(techniques) != 1)}.")
    return "\\textbf{" + esc(line) + "}"


def _claim_cause(c: dict) -> list[str]:
    out = []
    f = c.get("factor")
    if f and f.get("mean_with") is not None:
        out.append(f"{c['claim']} {findings_text.factor_text(c)}")
    gt = c.get("ground_truth")
    if gt:
        unit = c["unit"].split(",")[0]
        d = findings_text._d(c)
        out.append(f"Judged as the thesis judged (against {gt['name']}), {gt['holds']} of {gt['of']} cases of "
                   f"'{c['claim']}' take the thesis's side, {unit} {findings_text._num(gt['mean'], d)} on average "
                   f"against {findings_text._num(gt['mean_path_traced'], d)} against the path-traced reference: "
                   "the ground truth itself moves the verdict by the difference.")
    if c.get("resolution_note"):
        out.append(f"{c['claim']} Resolution: {c['resolution_note']}.")
    if c.get("machine"):
        out.append(f"{c['claim']} Timings: {c['machine']}.")
    return out


def discussion(record: dict | None) -> str:
    """The measured causes, one paragraph each; a sentence saying none was measured otherwise."""
    if record is None:
        return esc("This study has no findings record, so it measured no cause.")
    paras = [s for c in record["claims"] if c["cases"] for s in _claim_cause(c)]
    paras += [t for t in map(findings_text.factor_sentence, record.get("factors", [])) if t]
    if not paras:
        return esc("This study ran none of the cases that measure a cause (the thesis's scenes with both TAAs, "
                   "their unsharpened variants and the sharpen sweep): no cause is measured here.")
    return "\n\n".join(esc(p) for p in paras)


def _git(*args: str) -> str | None:
    try:
        r = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def reproducibility(manifest: Path, summary: dict) -> str:
    """The command that rebuilds the study and the paper, the commit of the code that built it and
    the SHA-256 of the study's manifest (which lists every artefact with its own hash)."""
    digest = hashlib.sha256(Path(manifest).read_bytes()).hexdigest()
    commit = _git("rev-parse", "HEAD")
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    profile = summary.get("profile")
    cmd = f"taa-study paper --profile {profile}" if profile else "taa-study paper STUDY_FILE"
    code = ("no git checkout (the commit is unknown)" if commit is None else
            f"commit {commit}" + (" with uncommitted changes to tracked files" if dirty else ""))
    lines = [f"\\item Command: \\texttt{{{esc(cmd)}}} (it runs the study, reusing every cached result, then "
             "regenerates \\texttt{paper/generated/} and builds this PDF).",
             f"\\item Code: {esc(code)}.",
             f"\\item Study manifest (\\texttt{{manifest.json}}, every artefact with its SHA-256): SHA-256 "
             f"\\newline\\texttt{{{digest}}}."]
    if summary.get("seconds") is not None:
        lines.append(esc(f"\\item The study: {summary.get('runs_computed', 0)} runs computed and "
                         f"{summary.get('runs_cached', 0)} cached, {summary.get('references_rendered', 0)} "
                         f"references rendered, {summary['seconds']:.0f} s wall in its last invocation "
                         f"({summary.get('executor', 'unknown executor')}).").replace("\\textbackslash{}item", "\\item"))
    return "\\begin{itemize}\n" + "\n".join(lines) + "\n\\end{itemize}"


__all__ = ["scope", "discussion", "reproducibility", "esc"]
