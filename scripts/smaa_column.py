"""Print the SMAA column of the quick static test: display 8-bit PSNR against the Mitsuba reference.

For each scene: the unjittered frame of scene time 0 (raster.Rasterizer), its reference from
references.ReferenceCache (the quick profile's convergence target; cached under .cache/taa-study),
the display transform from that reference, then SMAA (and, for context, No AA and FXAA) on the
display image, PSNR as study.metrics.suite computes it.

    .venv/bin/python scripts/smaa_column.py [--scenes a,b,...] [--size 320x180]
        [--param name=value ...] [--baseline GIT_REV] [--refs DIR] [--json out.json]

`--param` overrides an SMAAParams field (e.g. --param area=exact), to compare variants.
`--baseline REV` also runs the SMAA of that git revision (its taa_impl/smaa*.py with the kernels
it was written against) on the same frames and references, and prints the difference: references
are keyed by the reference code, so a column measured on another day may rest on other references.
`--refs DIR` reads the references from DIR/<scene>.exr (copies of cached references) instead of
the cache, to pin them across code changes.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

DEFAULT_SCENES = ("pipe", "pipe_tilted", "blinds", "hard_edges", "subpixel_lines", "hairball_unlit",
                  "hairball_lit", "arched_window", "atrium", "flowers", "text_wall")


def fail(msg: str):
    print(f"smaa_column: {msg}", file=sys.stderr)
    sys.exit(2)


def parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        fail(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 320x180")
    if w < 4 or h < 4:
        fail(f"--size {text!r}: width and height must be >= 4")
    return w, h


def parse_params(items: list[str]) -> dict:
    from taa_impl.smaa import SMAAParams
    fields = {f.name: f for f in dataclasses.fields(SMAAParams)}
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in fields:
            fail(f"--param {item!r}: expected NAME=VALUE with NAME one of {sorted(fields)}")
        default = fields[name].default
        try:
            out[name] = type(default)(value) if not isinstance(default, str) else value
        except ValueError:
            fail(f"--param {item!r}: {value!r} is not a {type(default).__name__}")
    try:
        SMAAParams(**out)
    except ValueError as e:
        fail(f"--param: {e}")
    return out


def revision_smaa(rev: str):
    """The SMAA technique as it was at git revision `rev`, imported as a separate package."""
    root = Path(__file__).resolve().parent.parent
    pkg = Path(tempfile.mkdtemp(prefix="smaa_rev_")) / "taa_impl_rev"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name in ("smaa.py", "smaa_area.py", "kernels.py", "base.py", "sanitize.py"):
        got = subprocess.run(["git", "-C", str(root), "show", f"{rev}:taa_impl/{name}"],
                             capture_output=True, text=True)
        if got.returncode != 0:
            fail(f"--baseline {rev!r}: cannot read taa_impl/{name} there ({got.stderr.strip()})")
        (pkg / name).write_text(got.stdout)
    sys.path.insert(0, str(pkg.parent))
    import importlib
    return importlib.import_module("taa_impl_rev.smaa").SMAA()


def pinned_reference(path: Path, shape):
    import numpy as np
    from references.exr import read_exr
    if not path.is_file():
        fail(f"--refs: no reference file {path}")
    try:
        _, ch = read_exr(path)
        img = np.stack([ch[c] for c in "RGB"], -1).astype(np.float32)
    except Exception as exc:   # any unreadable file is the user's input error here
        fail(f"--refs: cannot read {path}: {exc}")
    if img.shape != shape:
        fail(f"--refs: {path} is {img.shape[1]}x{img.shape[0]}, expected {shape[1]}x{shape[0]}")
    return img


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(DEFAULT_SCENES))
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--param", action="append", default=[])
    ap.add_argument("--baseline", metavar="GIT_REV")
    ap.add_argument("--refs", type=Path, metavar="DIR")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    w, h = parse_size(args.size)
    overrides = parse_params(args.param)

    import numpy as np

    import taa_impl
    from display import DisplayTransform
    from raster import Rasterizer
    from references import ReferenceCache
    from scenes import builtin_names, get_scene
    from study.metrics import suite as M
    from study.config import defaults

    names = [s for s in args.scenes.split(",") if s]
    unknown = [s for s in names if s not in builtin_names()]
    if unknown:
        fail(f"--scenes: unknown scene(s) {unknown}; built-ins: {', '.join(builtin_names())}")

    cache = ReferenceCache(log=lambda m: print(m, file=sys.stderr))
    target = defaults.REFERENCE["target_noise_db"]
    techs = {"No AA": taa_impl.make("noaa"), "FXAA": taa_impl.make("fxaa"),
             "SMAA": taa_impl.make("smaa", **overrides)}
    if args.baseline:
        techs["SMAA@base"] = revision_smaa(args.baseline)
    rows = {}
    print(f"# {w}x{h}, static test frame t=0, PSNR (dB, 8-bit display) vs the Mitsuba reference;"
          f" SMAA overrides {overrides or 'none'}")
    base = f" {'SMAA@' + args.baseline[:8]:>14} {'change':>7}" if args.baseline else ""
    print(f"{'scene':<16} {'No AA':>7} {'FXAA':>7} {'SMAA':>7}{base}  {'SMAA s':>6}")
    for name in names:
        scene = get_scene(name)
        if args.refs:
            ref_img = pinned_reference(args.refs / f"{name}.exr", (h, w, 3))
        else:
            ref_img = cache.get(scene, 0, w, h, target_noise_db=target)[0].image
        dt = DisplayTransform.from_reference(ref_img)
        ref8 = dt.to_8bit(ref_img)
        raster = Rasterizer(scene, w, h)
        try:
            frame = raster.render(0, (0.0, 0.0), ("color",), prev_t=0)
        finally:
            raster.close()
        far = scene.desc.camera.far
        row = {}
        for label, tech in techs.items():
            t0 = time.perf_counter()
            img = tech.process(frame, jitter=(0.0, 0.0), far=far, reset=True, display=dt)
            secs = time.perf_counter() - t0
            if tech.output_space == "display":
                x8 = np.round(np.clip(np.asarray(img, np.float64), 0, 1) * 255).astype(np.uint8)
            else:
                x8 = dt.to_8bit(img)
            row[label] = M.psnr_from_mse(M.mse(ref8, x8))
            if label == "SMAA":
                row["smaa_seconds"] = secs
        rows[name] = row
        extra = (f" {row['SMAA@base']:14.2f} {row['SMAA'] - row['SMAA@base']:+7.2f}"
                 if args.baseline else "")
        print(f"{name:<16} {row['No AA']:7.2f} {row['FXAA']:7.2f} {row['SMAA']:7.2f}{extra}  "
              f"{row['smaa_seconds']:6.2f}", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"size": [w, h], "overrides": overrides,
                                              "baseline": args.baseline, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
