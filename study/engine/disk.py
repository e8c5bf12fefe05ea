"""The disk a study's plan needs in the cache, and which tests' runs stay whole while they refine.

Under the figures' rule a test's runs keep every judged frame until the test settles, so that a
finer reference is judged without making the run again. At 1600x900 a judged frame is ~8.5 MB
(float32 EXR, ZIP: about half raw) and the full profile judges ~19,000 of them: ~200 GB whole. Its
first run filled this machine's disk after 75 minutes. The tests whose runs do not fit beside
everything else the plan writes are pruned once judged instead (to the frames the report reads),
and their runs are made again if their references are refined: time, not disk. A plan that cannot
fit even so stops before computing anything, naming the folder and the sizes.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from study.engine.tasks import TaskError

# bytes a pixel takes on disk, measured on the cache's 1600x900 files: a run's judged frame (RGB,
# 5.9-6.4), a reference (its image, halves' difference, standard errors, floor and spp: 10-15.3),
# a frame's maps (SSIM, FLIP LDR and HDR)
FRAME_BYTES, REFERENCE_BYTES, MAPS_BYTES = 7, 16, 12
# left free for everything else (logs, the report, the OS): a quarter of what the plan keeps,
# between 64 MB and 2 GB (a fixed 2 GB refused a 250 KB study on a small disk)
MARGIN, MARGIN_MIN, MARGIN_SHARE = 2 * 2 ** 30, 64 * 2 ** 20, 0.25
IN_FLIGHT = 4                 # runs judged at once (whole between their run and metrics tasks)


class DiskError(TaskError):
    """The plan's files cannot fit in the cache's free space, however its runs are pruned."""


def needs(plan) -> dict:
    """What the plan writes: {'references', 'maps': bytes, 'tests': (scene, protocol) -> (bytes
    of its new runs whole, bytes once pruned to their kept frames), 'run': the most one run's
    pruning frees}. A run two tests read counts once, for the first."""
    refs = sum(t.spec.width * t.spec.height * REFERENCE_BYTES for t in plan.tasks.values()
               if t.kind == "reference" and not t.likely_cached)
    made = {k for t in plan.tasks.values() if t.kind == "run" for k in t.spec.keys.values()}   # runs it makes
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
            whole, kept, run = whole + n * px * FRAME_BYTES, kept + k * px * FRAME_BYTES, max(run, (n - k) * px * FRAME_BYTES)
            maps += len(test.maps_for[label]) * px * MAPS_BYTES
        if whole:
            k = (test.scene, test.protocol.name)
            w0, k0 = tests.get(k, (0, 0))
            tests[k] = (w0 + whole, k0 + kept)
    return {"references": refs, "maps": maps, "tests": tests, "run": run}


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


def fit(need: dict, free: int, figures: bool, folder: Path, already: frozenset = frozenset(),
        log=print) -> frozenset:
    """The tests whose runs are pruned once judged: `already` and, if the others' runs do not all
    fit whole, the largest (by the bytes keeping them whole costs) until the rest fit. With
    `figures` False (the per-pixel rule, nothing refined) every test is. Raises DiskError if the
    plan does not fit even so (checked each round: finer references take room too)."""
    tests = need["tests"]
    kept = need["maps"] + sum(k for _, k in tests.values())
    flight = IN_FLIGHT * need.get("run", 0)          # runs whole between their run and metrics tasks
    spare = margin(need)
    floor = need["references"] + kept + flight + spare
    gb = 2 ** 30
    if floor > free:
        raise DiskError(f"the study needs about {size(floor)} in the cache folder {folder} (references "
                        f"{size(need['references'])}, the runs' kept frames and maps {size(kept)}, "
                        f"{IN_FLIGHT} runs being judged {size(flight)}, {size(spare)} spare: "
                        f"{MARGIN_SHARE:.0%} of these, {size(MARGIN_MIN)} to {size(MARGIN)}) and "
                        f"{size(free)} is free: free some, or set TAA_STUDY_CACHE to a larger disk")
    if not figures:
        return frozenset(tests)
    room, whole = free - floor, set()
    for k, (w, kept) in sorted(tests.items(), key=lambda x: x[1][0] - x[1][1]):   # the cheapest to keep first
        if k not in already and w - kept <= room:
            room -= w - kept
            whole.add(k)
    pruned = frozenset(tests) - whole - already
    if pruned:
        extra = sum(tests[k][0] - tests[k][1] for k in pruned)
        log(f"disk: {len(pruned)} of {len(tests)} tests' runs ({extra / gb:.1f} GB whole) do not fit in the "
            f"{free / gb:.1f} GB free beside the rest: pruned once judged, and made again if their references are refined")
    return pruned | already


def free_bytes(folder: Path) -> int:
    """Free bytes on the disk that holds (or will hold) `folder`."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:     # a cache not made yet
        folder = folder.parent
    return shutil.disk_usage(folder).free
