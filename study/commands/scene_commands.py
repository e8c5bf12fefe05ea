"""The commands that look at one scene: `scenes`, `agree` (the raster against its reference) and
`render` (the raster's buffers and the reference as files)."""
from __future__ import annotations

import sys

import click

from references import settings as reference_settings
from scenes.description import MAX_SIDE
from study.commands.common import (_cache_folder, _check_render_size, _fail, _scene_and_size, _strict_json,
                                   _writable_folder, main)


@main.command()
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list instead of a table.")
def scenes(as_json):
    """List the built-in scenes."""
    from scenes import builtin_names, get_scene
    rows = []
    for name in builtin_names():
        s = get_scene(name)
        d = s.desc
        rows.append({"name": name, "frames": d.frames, "width": d.resolution.quick[0],
                     "height": d.resolution.quick[1], "full_width": d.resolution.full[0],
                     "full_height": d.resolution.full[1], "objects": len(d.objects),
                     "triangles": int(sum(len(m.faces) for m in s.meshes)), "lights": len(d.lights),
                     "transport": d.transport, "features": d.features(), "stresses": d.stresses})
    if as_json:
        click.echo(_strict_json(rows))
        return
    for r in rows:
        click.echo(f"{r['name']:16s} {r['frames']:4d} frames  quick {r['width']}x{r['height']}  "
                   f"full {r['full_width']}x{r['full_height']}  {r['objects']:3d} objects "
                   f"{r['triangles']:6d} tris  {r['transport']:15s} {', '.join(r['features'])}")
        click.echo(f"{'':16s} stresses: {r['stresses']}")


def _print_agreement(a) -> None:
    from study.engine.agreement import TARGETS
    ok = a.meets_targets()
    mark = {True: "ok", False: "BELOW TARGET"}
    click.echo(f"scene {a.scene}, frame {a.frame}, {a.width}x{a.height}")
    click.echo(f"  agreement PSNR (display, {a.raster_samples} raster frames vs reference): "
               f"{a.agreement_psnr_db:.2f} dB  [target >= {TARGETS['agreement_psnr_db']}: {mark[ok['agreement_psnr_db']]}]")
    click.echo(f"  relative MSE (linear HDR): {a.relative_mse:.3e}")
    click.echo(f"  interior max |raster - Mitsuba ray| at pixel centres: {a.interior_max_abs_err:.2e} "
               f"over {a.interior_pixels} pixels  [target <= {TARGETS['interior_max_abs_err']:g}: "
               f"{mark[ok['interior_max_abs_err']]}]")
    click.echo(f"  reference: {a.reference_spp} spp mean, {a.reference_spp_max} max, {a.reference_seconds:.1f} s"
               f"{' (cached)' if a.reference_cached else ''}, noise PSNR {a.reference_noise_psnr_db:.2f} dB"
               f"  [target >= {TARGETS['reference_noise_psnr_db']}: {mark[ok['reference_noise_psnr_db']]}]")
    click.echo(f"  reference per-pixel SE: bound {a.reference_se_bound_lsb:g} LSB, p99.9 {a.reference_se_p999_lsb:.3f}, "
               f"max {a.reference_se_max_lsb:.3f}, {a.reference_over_bound} pixels over"
               + (f" (at the cap; the worst would take ~{a.reference_spp_needed} spp)" if a.reference_over_bound else "")
               + "  "
               f"[{'held' if ok['reference_bound'] else 'BOUND MISSED'}]")
    click.echo(f"  objects visible at {100 * a.visible_fraction:.1f} % of pixel centres  "
               f"[{'ok' if ok['objects_visible'] else 'NOTHING TO COMPARE: background only'}]")
    click.echo(f"  single sample per pixel: {a.single_sample} (pixel centres matching a single ray: "
               f"{100 * a.centre_match_fraction:.3f} %)")


@main.command()
@click.option("--scene", "scene_names", multiple=True, help="Built-in scene name or scene file (repeatable).")
@click.option("--all", "all_builtin", is_flag=True, help="Every built-in scene.")
@click.option("--frame", default=0, show_default=True, help="Frame index of the scene's animation.")
@click.option("--profile", type=click.Choice(["quick", "full"]), default="quick", show_default=True)
@click.option("--width", type=click.IntRange(min=8, max=MAX_SIDE), help="Override the profile's width.")
@click.option("--height", type=click.IntRange(min=8, max=MAX_SIDE), help="Override the profile's height.")
@click.option("--samples", default=256, show_default=True, type=click.IntRange(min=1),
              help="Jittered raster frames averaged.")
@click.option("--target-noise-db", default=reference_settings.TARGET_NOISE_DB, show_default=True,
              help="Reference convergence target (display-domain noise PSNR).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (a list with several scenes).")
def agree(scene_names, all_builtin, frame, profile, width, height, samples, target_noise_db, as_json):
    """Prove the raster and the Mitsuba reference agree on one scene frame.

    Exits 1 when a scene misses a target (agreement >= 45 dB, interior error <= 1e-4,
    reference noise >= 55 dB, every reference pixel within its SE bound, single-sample raster,
    objects visible)."""
    from scenes import builtin_names
    names = list(scene_names) + (builtin_names() if all_builtin else [])
    if not names:
        _fail("name a scene with --scene NAME or use --all")
    if samples < 1:
        _fail(f"--samples must be >= 1, got {samples}")
    _cache_folder()
    from study.engine.agreement import check_agreement
    results = []
    for name in names:
        scene, w, h = _scene_and_size(name, profile, width, height)
        _check_render_size(w, h, f"--scene {name}")
        if frame < 0 or frame >= scene.desc.frames:
            _fail(f"scene {name!r} has frames 0..{scene.desc.frames - 1}; --frame {frame} is out of range")
        a = check_agreement(scene, w, h, frame=frame, samples=samples, target_noise_db=target_noise_db,
                            progress=not as_json)
        results.append(a)
        if not as_json:
            _print_agreement(a)
    if as_json:
        out = [a.as_dict() for a in results]
        click.echo(_strict_json(out[0] if len(out) == 1 else out))
    if not all(all(a.meets_targets().values()) for a in results):
        sys.exit(1)


@main.command()
@click.option("--scene", "scene_name", required=True, help="Built-in scene name or scene file.")
@click.option("--frame", default=0, show_default=True)
@click.option("--profile", type=click.Choice(["quick", "full"]), default="quick", show_default=True)
@click.option("--width", type=click.IntRange(min=8, max=MAX_SIDE), help="Override the profile's width.")
@click.option("--height", type=click.IntRange(min=8, max=MAX_SIDE), help="Override the profile's height.")
@click.option("--jitter", nargs=2, type=float, default=(0.0, 0.0), show_default=True,
              help="Sub-pixel offset (ox, oy) of the raster frame's sample.")
@click.option("--buffers", default="color,albedo,depth,object_id,motion", show_default=True,
              help="Comma-separated raster buffers to write.")
@click.option("--no-reference", is_flag=True, help="Write the raster buffers only.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True)
def render(scene_name, frame, profile, width, height, jitter, buffers, no_reference, out_dir):
    """Write one frame's raster buffers (EXR) and its reference (EXR + display PNG)."""
    import numpy as np
    from PIL import Image

    from display import DisplayTransform
    from raster import BUFFERS, Rasterizer
    from references import ReferenceCache
    from references.exr import write_exr

    scene, w, h = _scene_and_size(scene_name, profile, width, height)
    _check_render_size(w, h, f"--scene {scene_name}")
    wanted = [b.strip() for b in buffers.split(",") if b.strip()]
    bad = [b for b in wanted if b not in BUFFERS]
    if bad:
        _fail(f"unknown buffer(s) {bad}; available: {', '.join(BUFFERS)}")
    if not 0 <= frame < scene.desc.frames:
        _fail(f"scene {scene.name!r} has frames 0..{scene.desc.frames - 1}; --frame {frame} is out of range")
    out = _writable_folder(out_dir, "--out")
    if not no_reference:
        _cache_folder()
    r = Rasterizer(scene, w, h)
    try:
        bufs = r.render(frame, jitter, wanted)
    finally:
        r.close()
    ref = None
    if not no_reference:      # before any file is written: a failing reference leaves no half output
        ref, cached = ReferenceCache().get(scene, frame, w, h)
    stem = f"{scene.name}_f{frame:04d}"
    for name, a in bufs.items():
        a = a.astype(np.float32)
        chans = {"RGB": a} if a.ndim == 3 and a.shape[2] == 3 else \
            {f"{name}.{'xy'[k]}": a[..., k] for k in range(a.shape[2])} if a.ndim == 3 else {name: a}
        write_exr(out / f"{stem}_{name}.exr", chans, {"taa_jitter": f"{jitter[0]} {jitter[1]}"})
    disp = None
    if ref is not None:
        write_exr(out / f"{stem}_reference.exr", {"RGB": ref.image}, {"taa_spp": ref.spp})
        disp = DisplayTransform.from_reference(ref.image)
        Image.fromarray(disp.to_8bit(ref.image)).save(out / f"{stem}_reference.png")
        click.echo(f"reference: {ref.spp} spp, noise PSNR {ref.noise_psnr_db:.1f} dB"
                   f"{' (cached)' if cached else ''}")
    if "color" in bufs:
        disp = disp or DisplayTransform.from_reference(bufs["color"])
        Image.fromarray(disp.to_8bit(bufs["color"])).save(out / f"{stem}_raster.png")
    click.echo(f"wrote {len(list(out.glob(stem + '*')))} files to {out}/")
