"""The disk a study's plan needs in the cache, and which tests' runs stay whole while they refine.

Under the figures' rule a test's runs keep every judged frame until the test settles, so that a
finer reference is judged without making the run again. At 1600x900 a judged frame is ~9 MB
(float32 EXR, ZIP) and the full profile judges ~19,000 of them: ~200 GB whole. Its first run
filled this machine's disk after 75 minutes. The tests whose runs do not fit beside everything
else the plan writes are pruned once judged instead, and their runs are made again if their
references are refined: time, not disk; a profile may ask for that of every test
(`runs = "pruned"`, the thesis profile). A run pruned once judged is judged as it is made
(study.engine.run_task): it never holds a float frame, and what the report shows of it (a ghosting
test's 24 slider frames, a static view) is kept as the 8-bit PNG it shows, in its metrics record.
A plan that cannot fit even so stops before computing anything, naming the folder and the sizes.

What a settled test keeps: its references (the expensive asset, re-keyed only by code changes;
Zstandard), its metrics records with their SSIM/FLIP maps (the
report's and paper's map images and EXR) and the PNGs of the frames the report shows; its runs'
done records (what a later study checks) with no frame, unless kept whole (`keep_frames = "all"`,
the video metric's columns, or runs kept whole while refining, pruned to their shown frames once
settled). Every file is lossless (a figure computed from it must not move): the sizes below are
real files' (docs/performance.md, "Disk"; scripts/measure_disk.py).
"""
from __future__ import annotations

import shutil
from pathlib import Path

from references.cache import reuse_on
from study.engine.tasks import TaskError

# Bytes a pixel takes on disk, measured on real 1600x900 files (scripts/measure_disk.py): a run's
# judged frame (float RGB, ZIP: 5.9-6.4 for the thesis scenes' TAA frames), a reference (image,
# standard errors, floor, halves' difference, spp; Zstandard, measured as the smaller of it and ZIP: sphere_ghosting
# 23.4, whose floor's path-traced noise ZIP kept at 36.7; hairball_rotating_unlit 11.0, hard_edges 6.3,
# pipe 1.2),
# a reference's sample extremes, stored for reuse until the next frame is made (references.cache:
# sphere_ghosting 17, hard_edges 1, ZIP), a frame's maps (SSIM, FLIP LDR and HDR, Zstandard: 0.8-6.3 measured on No
# AA's frames, 10 on the noisiest), a frame shown by the report, kept as its 8-bit PNG
# (0.02-0.14 for a raster frame, SHOWN_BYTES for the most detailed TAA output measured)
FRAME_BYTES, REFERENCE_BYTES, EXTREMES_BYTES, MAPS_BYTES, SHOWN_BYTES = 7, 24, 18, 11, 1
# a reference's bytes a pixel where measured at 1600x900 (the smaller of ZIP and Zstandard, rounded
# up): the thesis's scenes; the nine static ones and hairball_rotating_lit took 10-15.3 in ZIP, and
# in Zstandard alone (what references are written in) at most 14.6 (blinds)
REFERENCE_BYTES_OF = {"sphere_ghosting": 24, "hairball_rotating_unlit": 12, "pipe": 2, "hard_edges": 7,
                      **dict.fromkeys(("pipe_tilted", "blinds", "arched_window", "atrium", "flowers",
                                       "hairball_unlit", "hairball_lit", "hairball_rotating_lit"), 16)}
FILE_BYTES = 4096             # each file's header and offsets (a reference's header is ~1.8 KB)
# left free for everything else (logs, the report, the OS): a quarter of what the plan keeps,
# between 64 MB and 2 GB (a fixed 2 GB refused a 250 KB study on a small disk)
MARGIN, MARGIN_MIN, MARGIN_SHARE = 2 * 2 ** 30, 64 * 2 ** 20, 0.25
IN_FLIGHT = 4                 # runs judged at once (whole between their run and metrics tasks) but
                              # those judged as they are made


class DiskError(TaskError):
    """The plan's files cannot fit in the cache's free space, however its runs are pruned."""


def needs(plan) -> dict:
    """What the plan writes: {'references', 'maps': bytes, 'tests': (scene, protocol) -> (bytes
    of its new runs whole, bytes once pruned to what the report shows), 'run': the most one run's
    pruning frees, of the runs written whole before they are judged}. A run two tests read counts
    once, for the first. A run whose shown frames are kept as 8-bit PNGs (every run but those the
    video metric reads) is judged as it is made once pruned: never whole on disk then."""
    new = [t for t in plan.tasks.values() if t.kind == "reference" and not t.likely_cached]
    refs = sum(file_bytes("reference", t.spec.width, t.spec.height, scene=t.spec.scene) for t in new)
    # a reference's sample extremes stay only until the next frame of its chain is made from them
    # (references.cache): each chain's last frame's, and those of the frames being rendered
    chains = {(t.spec.scene, t.spec.width, t.spec.height, repr(sorted(t.spec.settings.items()))): t.spec
              for t in new if reuse_on(t.spec.scene, t.spec.settings.get("reuse"))}
    refs += (len(chains) + IN_FLIGHT) * max([file_bytes("extremes", c.width, c.height) for c in chains.values()] or [0])
    made = {k for t in plan.tasks.values() if t.kind == "run" for k in t.spec.keys.values()}   # runs it makes
    as_png = {it["key"]: it.get("shown_8bit", True) for t in plan.tasks.values() if t.kind == "metrics"
              for it in t.spec.items}
    seen, tests, maps, run = set(), {}, 0, 0
    for test in plan.tests:
        px = test.width * test.height
        whole = kept = 0
        for label, key in test.run_keys.items():
            if key not in made or key in seen:
                continue
            seen.add(key)
            n = len(test.frame_times[label])
            k = n if test.keep[label] is None else len(test.keep[label])
            frame = file_bytes("frame", test.width, test.height)
            if as_png.get(test.metrics_keys[label], True):      # judged as made once pruned, kept as shown
                whole, kept = whole + n * frame, kept + k * file_bytes("shown", test.width, test.height)
            else:
                whole, kept, run = whole + n * frame, kept + k * frame, max(run, (n - k) * frame)
            maps += len(test.maps_for[label]) * file_bytes("maps", test.width, test.height)
        if whole:
            k = (test.scene, test.protocol.name)
            w0, k0 = tests.get(k, (0, 0))
            tests[k] = (w0 + whole, k0 + kept)
    return {"references": refs, "maps": maps, "tests": tests, "run": run}


def file_bytes(kind: str, width: int, height: int, scene: str | None = None) -> int:
    """The bytes one file takes on disk, at most (as measured: see the constants).

    Parameters
    ----------
    kind : {'frame', 'reference', 'extremes', 'maps', 'shown'}
        A run's judged frame, a reference, a reference's sample extremes (kept beside it until the
        next frame is made from them, references.cache), a judged frame's SSIM/FLIP maps, or a frame
        the report shows kept as its 8-bit PNG.
    width, height : int
        Its size in pixels.
    scene : str, optional
        A reference's scene: its measured size (REFERENCE_BYTES_OF) if it has one.
    """
    per = {"frame": FRAME_BYTES, "reference": REFERENCE_BYTES_OF.get(scene, REFERENCE_BYTES), "maps": MAPS_BYTES,
           "shown": SHOWN_BYTES, "extremes": EXTREMES_BYTES}[kind]
    return width * height * per + FILE_BYTES


def margin(need: dict) -> int:
    """The bytes left free beside what the plan `need` (needs) keeps: MARGIN_SHARE of it, between
    MARGIN_MIN and MARGIN."""
    keeps = need["references"] + need["maps"] + sum(k for _, k in need["tests"].values()) \
        + IN_FLIGHT * need.get("run", 0)
    return int(min(MARGIN, max(MARGIN_MIN, MARGIN_SHARE * keeps)))


def size(n: float) -> str:
    """Bytes for a message: GB, MB or KB, whichever reads."""
    for unit, b in (("GB", 2 ** 30), ("MB", 2 ** 20)):
        if n >= b:
            return f"{n / b:.1f} {unit}"
    return f"{n / 2 ** 10:.1f} KB"


def summary(need: dict, free: int, pruned: bool, removing: bool | None = None, budget: int | None = None) -> dict:
    """What `estimate` reports of the plan's disk `need` (needs), in GB: references, maps, runs whole
    and pruned, `free`, the peak with every test's runs whole while it refines, the least (every
    test's runs pruned once judged, IN_FLIGHT being judged), each with its margin, and the peak
    planned: the least if `pruned` (the profile's runs_while_refining, or nothing refined).
    `removing`: superseded artefacts removed as the study refines (keep_superseded false): each
    peak is the max over rounds, a finer round's references in place of those they replace (these
    are removed before it renders, the probe's too: their display transforms stay as records);
    False: they are kept, and the figures price the first round only (each refinement adds its
    references and records); None: nothing is refined (the per-pixel rule). `budget`: the profile's
    disk_budget_gb in bytes, which runs kept whole stay within (fit): the peak planned is then at
    most it, or the least if that is over it."""
    gb = 2 ** 30
    tests = need["tests"].values()
    whole, kept = sum(w for w, _ in tests), sum(k for _, k in tests)
    out = {"references_gb": need["references"] / gb, "maps_gb": need["maps"] / gb, "runs_whole_gb": whole / gb,
           "runs_kept_gb": kept / gb, "free_gb": free / gb,
           "peak_gb": (need["references"] + need["maps"] + whole + margin(need)) / gb,
           "least_gb": (need["references"] + need["maps"] + kept + IN_FLIGHT * need["run"] + margin(need)) / gb,
           "runs_while_refining": "pruned" if pruned else "whole",
           "superseded": {True: "removed", False: "kept", None: "none"}[removing],
           "budget_gb": None if budget is None else budget / gb}
    out["planned_gb"] = out["least_gb"] if pruned else out["peak_gb"]
    if not pruned and budget is not None:
        out["planned_gb"] = min(out["peak_gb"], max(out["least_gb"], budget / gb + margin(need) / gb))
    return out


def describe(disk: dict, remake_s: float | None = None) -> list[str]:
    """`estimate`'s lines for a `summary`; `remake_s`: the measured seconds of the plan's runs (what
    a refinement round remakes at most when they are pruned)."""
    pruned = disk["runs_while_refining"] == "pruned"
    within = disk.get("budget_gb") is not None and not pruned and disk["planned_gb"] < disk["peak_gb"]
    cost = (f"; within the profile's disk_budget_gb of {disk['budget_gb']:.0f} GB: the rest pruned once judged, "
            "the tests cheapest to keep whole kept" if within else "") + ("" if not pruned else "; each refinement round remakes the refined tests' runs, " + (
        f"at most {remake_s / 60:.0f} min a round" if remake_s is not None else "their time: --measure"))
    return [f"disk: references {disk['references_gb']:.1f} GB, runs {disk['runs_whole_gb']:.1f} GB whole while "
            f"their tests refine ({disk['runs_kept_gb']:.1f} GB once pruned to the frames the report reads), "
            f"maps {disk['maps_gb']:.1f} GB; {disk['free_gb']:.1f} GB free in the cache's disk (study.engine.disk)",
            f"disk at its peak: {disk['peak_gb']:.1f} GB with every test's runs whole, at least "
            f"{disk['least_gb']:.1f} GB with runs pruned once judged (a test refined again then remakes "
            f"its runs), each with its margin",
            f"disk planned: {disk['planned_gb']:.1f} GB (runs {disk['runs_while_refining']} while their tests "
            f"refine: the profile's runs_while_refining{cost})", _assumes(disk)]


def _assumes(disk: dict) -> str:
    """`estimate`'s line on which rounds the peaks price (summary's `superseded`)."""
    sup = disk.get("superseded", "none")
    if sup == "removed":
        return ("disk peaks hold over every round: a reference a finer bound replaces (the probe's too: its display "
                "transform stays as a record), and the metrics records judged against it, are removed before the "
                "finer round renders (keep_superseded = false)")
    if sup == "kept":
        return ("disk peaks price the first round only: each refinement round adds its references and metrics records, "
                "and a superseded one stays for a later study (keep_superseded = true)")
    return "disk peaks: one round (nothing is refined under the per-pixel rule)"


def fit(need: dict, free: int, figures: bool, folder: Path, already: frozenset = frozenset(),
        log=print, budget: int | None = None) -> frozenset:
    """The tests whose runs are pruned once judged: `already` and, if the others' runs do not all
    fit whole, the largest (by the bytes keeping them whole costs) until the rest fit. With
    `figures` False (the per-pixel rule, nothing refined) every test is. Raises DiskError if the
    plan does not fit even so (checked each round: finer references take room too).
    `budget`: the bytes the cache may still grow by under the profile's disk_budget_gb; runs are
    kept whole only within it too (a budget too small for the rest prunes every test, not an error:
    it is a target, the free disk the limit)."""
    tests = need["tests"]
    kept = need["maps"] + sum(k for _, k in tests.values())
    flight = IN_FLIGHT * need.get("run", 0)          # runs whole between their run and metrics tasks
    spare = margin(need)
    floor = need["references"] + kept + flight + spare
    gb = 2 ** 30
    if floor > free:
        raise DiskError(f"the study needs about {size(floor)} in the cache folder {folder} (references "
                        f"{size(need['references'])}, the runs' kept frames and maps {size(kept)}, "
                        f"{IN_FLIGHT} runs being judged {size(flight)}, "
                        + f"{size(spare)} spare: "
                        f"{MARGIN_SHARE:.0%} of these, {size(MARGIN_MIN)} to {size(MARGIN)}) and "
                        f"{size(free)} is free: free some, or set TAA_STUDY_CACHE to a larger disk")
    if not figures:
        return frozenset(tests)
    # the budget is the cache's size: the margin left free for everything else is the disk's business
    room, whole = free - floor if budget is None else min(free - floor, budget - (floor - spare)), set()
    for k, (w, kept) in sorted(tests.items(), key=lambda x: x[1][0] - x[1][1]):   # the cheapest to keep first
        if k not in already and w - kept <= room:
            room -= w - kept
            whole.add(k)
    pruned = frozenset(tests) - whole - already
    if pruned:
        extra = sum(tests[k][0] - tests[k][1] for k in pruned)
        where = (f"{free / gb:.1f} GB free" if budget is None or free <= budget else
                 f"{max(budget, 0) / gb:.1f} GB the disk budget leaves")
        log(f"disk: {len(pruned)} of {len(tests)} tests' runs ({extra / gb:.1f} GB whole) do not fit in the "
            f"{where} beside the rest: pruned once judged, and made again if their references are refined")
    return pruned | already


def budget_left(budget_gb: float | None, folder: Path, freed: int = 0) -> int | None:
    """The bytes the cache folder may still grow by under a profile's disk_budget_gb (None: no
    budget): the budget less what the folder holds, plus what is about to be removed (`freed`)."""
    return None if budget_gb is None else int(budget_gb * 2 ** 30) - used_bytes(folder) + freed


def used_bytes(folder: Path) -> int:
    """Bytes the files under `folder` take (0 for a folder not made yet): what a disk budget counts."""
    import os
    n, stack = 0, [str(folder)]
    while stack:
        try:
            with os.scandir(stack.pop()) as it:
                for e in it:
                    if e.is_dir(follow_symlinks=False):
                        stack.append(e.path)
                    elif e.is_file(follow_symlinks=False):
                        n += e.stat(follow_symlinks=False).st_size
        except (FileNotFoundError, NotADirectoryError):
            pass
    return n


def free_bytes(folder: Path) -> int:
    """Free bytes on the disk that holds (or will hold) `folder`."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:     # a cache not made yet
        folder = folder.parent
    return shutil.disk_usage(folder).free
