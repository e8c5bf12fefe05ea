"""Which study the headline documents come from, and the line that names it.

The results document (docs/results.md and the README's block, `taa-study results`) and the paper
(`taa-study paper`) state the thesis's verdicts. They come from the thesis's own study at its
1600x900 (`make thesis`, the thesis profile) where a complete one exists, and from the quick study
(320x180, `make study`) otherwise:

    choose("auto")    the thesis profile's output folder if it holds a finished study, else the quick one's
    choose("thesis")  the thesis profile's folder, or SourceError saying why it is not finished
    choose("quick")   the quick profile's folder

A folder holds a finished study when its manifest.json parses, lists the figures and the findings
record (the files `taa-study results` and the paper read), names the profile it should, and no
report is half moved into place (study.commands.out_folder's marker). Each profile's folder is
its study file's `out`, else out/<name> (what `taa-study run --profile NAME` writes).

    study_line(summary, resolutions, manifest_sha256=None) -> str
        'the thesis study (profile thesis; 1600x900; commit 1a2b3c4d5e6f; 2026-12-06 07:15 UTC)',
        the words every headline document opens with.
"""
from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

SOURCES = ("auto", "thesis", "quick")
NEEDS = ("tables/figures.json", "tables/findings.json")
INCOMPLETE = ".taa-study-incomplete"      # study.commands.out_folder.INCOMPLETE (the layers point one way)
PROFILES = Path(__file__).resolve().parents[1] / "config" / "profiles"


class SourceError(ValueError):
    """The study asked for has no finished output folder; the message names the folder and why."""


@dataclass(frozen=True)
class Source:
    """A chosen study: its profile, its output folder, and why it was chosen (one line)."""
    profile: str
    folder: Path
    why: str


def out_folder(profile: str) -> Path:
    """A built-in profile's output folder: its study file's `out`, else out/<name>."""
    try:
        doc = tomllib.loads((PROFILES / f"{profile}.toml").read_text())
    except (OSError, tomllib.TOMLDecodeError):
        doc = {}
    return Path(doc.get("out") or f"out/{profile}")


def unfinished(folder, profile: str) -> str | None:
    """Why `folder` does not hold a finished study of `profile` (one phrase), or None if it does."""
    folder = Path(folder)
    mpath = folder / "manifest.json"
    if not mpath.is_file():
        return f"{folder} has no manifest.json: no study finished there"
    if (folder / INCOMPLETE).exists():
        return f"{folder} holds a report still being moved into place"
    try:
        manifest = json.loads(mpath.read_text())
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        return f"{mpath} cannot be read ({exc})"
    arts = manifest.get("artefacts") if isinstance(manifest, dict) else None
    summary = manifest.get("summary") if isinstance(manifest, dict) else None
    if not isinstance(arts, dict) or not isinstance(summary, dict):
        return f"{mpath} lists no artefacts or no summary"
    lacking = [rel for rel in NEEDS if rel not in arts or not (folder / rel).is_file()]
    if lacking:
        return f"{folder} lacks {', '.join(lacking)}"
    if summary.get("profile") != profile:
        return f"{folder} holds the {summary.get('profile')!r} study, not the {profile} profile's"
    return None


def choose(source: str = "auto", folders: dict | None = None) -> Source:
    """The study the headline documents come from (module docstring).

    Parameters
    ----------
    source : {'auto', 'thesis', 'quick'}
        'auto': the thesis study where its folder holds a finished one, else the quick study.
    folders : dict, optional
        Profile name -> output folder, instead of each profile's own (out_folder).

    Returns
    -------
    Source

    Raises
    ------
    SourceError
        `source` is 'thesis' and its folder holds no finished thesis study.
    ValueError
        `source` is not one of SOURCES.
    """
    if source not in SOURCES:
        raise ValueError(f"source {source!r}: expected one of {', '.join(SOURCES)}")
    folders = folders or {}
    thesis = Path(folders.get("thesis") or out_folder("thesis"))
    quick = Path(folders.get("quick") or out_folder("quick"))
    if source == "quick":
        return Source("quick", quick, "the quick study, as asked (--source quick)")
    why_not = unfinished(thesis, "thesis")
    if why_not is None:
        return Source("thesis", thesis, f"the thesis study at its own scale ({thesis} is finished)")
    if source == "thesis":
        raise SourceError(f"--source thesis: {why_not}; run `make thesis` (taa-study run --profile thesis) first, "
                          "or give --source quick")
    return Source("quick", quick, f"the quick study: no finished thesis study ({why_not})")


def _when(summary: dict) -> str:
    try:
        when = datetime.fromisoformat(summary["date"])
    except (KeyError, TypeError, ValueError):
        return "date not recorded"
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    return when.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def study_line(summary: dict, resolutions, manifest_sha256: str | None = None, date: str | None = None) -> str:
    """The study a document comes from, in words: its profile, resolutions, commit, (the manifest's
    sha256,) date. `date`: already formatted (else the summary's, in UTC)."""
    commit = summary.get("commit")
    commit = (f"commit {commit[:12]}{'+modified' if commit.endswith('+modified') else ''}"
              if isinstance(commit, str) and commit else "commit not recorded")
    profile = summary.get("profile") or "?"
    parts = [f"profile {profile}", ", ".join(resolutions) or "no static test", commit]
    if manifest_sha256:
        parts.append(f"manifest.json sha256 {manifest_sha256[:12]}")
    parts.append(date or _when(summary))
    return f"the {profile} study ({'; '.join(parts)})"


__all__ = ["choose", "unfinished", "out_folder", "study_line", "Source", "SourceError", "SOURCES"]
