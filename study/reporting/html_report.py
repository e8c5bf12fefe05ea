"""The study's interactive comparison report: one static page, out/report.html, that works from
file:// with no server and no network (its script and style are inlined; it shows the study's own
PNGs from out/images and out/maps by relative path).

    study.reporting.html_report.write(out_dir, data) -> out_dir / "report.html"

`data` (JSON-serialisable; every path relative to out_dir, and every file it names must exist):

    {"title": str, "profile": str,
     "source": str,                                  # optional: the study, in words (study.reporting.source.study_line)
     "findings": [sentence, ...],                    # optional: the prose findings
     "overview": "plots/overview.png",               # optional: the first screen's figure (report.Report.overview)
     "resolution": {scene: [width, height]},
     "scenes": {scene: {
         "agreement": {name: value, ...} or None,    # study.engine.agreement's dict, shown under the scene
         "reference_bound": str,                     # the reference's per-pixel noise bound, in words
         "plots": ["plots/....png", ...],            # optional: static figures shown under the scene
         "static": {protocol label: {
             "reference": "images/....png",
             "maps_note": str,                        # optional: what the maps' hatching marks (map_noise)
             "techniques": {label: {"image": "images/....png",
                                    "ssim_map": "maps/..._ssim.png" or None,
                                    "flip_map": "maps/..._flip.png" or None,
                                    "metrics": {"psnr": float, "ssim": float, "flip_ldr": float, ...}}}}},
         "ghosting": {protocol name: {
             "frames": [frame ids],
             "reference": ["images/....png", one per frame],
             "techniques": {label: {"images": [one per frame],
                                    "metrics": {metric: [value or None, one per frame]}}}}}}},
     "tables": {stem: {"title": str, "note": str (optional), "header": [str], "rows": [[str]],
                       "links": [[row, column, "images/....png"], ...]}}}

The first screen opens with the study it shows (profile, resolution, commit, date), then holds the overview figure and the verdict table (the findings table's claim,
thesis, ours and verdict columns, wrapped to the window); the prose findings follow. Tables are shown in the order headline, reproduction, history_convergence, speed_error, then the
rest as given; a linked cell opens its image in the viewer that holds it (or the file itself).

`collect(out_dir)` builds such a dict from a finished study folder alone (tables, images, maps,
manifest); it has no per-frame ghosting images or metrics, so its scenes have no ghosting viewers.

The viewer draws on a canvas with nearest-neighbour pixels. Its exposure control acts on the
display PNGs (tone-mapped, sRGB): an SVG filter decodes sRGB to linear, multiplies by 2^EV and
re-encodes, so +1 EV doubles the displayed linear light (clipped at white); it cannot bring back
highlights the tone map compressed.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from study.reporting.encode import slug

TABLE_ORDER = ("findings", "headline", "reproduction", "sharpen_test", "history_convergence", "speed_error")
# shown before the scenes, under the findings: what the study concludes, then the evidence
SUMMARY_TABLES = ("findings", "headline", "reproduction", "sharpen_test")
# the first screen's verdict table: these columns of the findings table (study.reporting.findings_text)
VERDICT_COLUMNS = ("claim", "thesis", "ours", "verdict")
KEYS_HELP = [
    ("1–9", "reference (1), techniques (2…)"), ("← → or [ ]", "previous / next image"),
    ("space", "back to the last image shown"), ("i s f", "image, SSIM map, FLIP map"),
    ("+ − 0", "zoom in, out, fit"), ("drag, wheel", "pan, zoom at the cursor"),
    ("e E x", "exposure +½ EV, −½ EV, reset"), (", .", "previous / next frame (ghosting)"),
]


class ReportDataError(ValueError):
    """`data` does not have the documented shape; the message names the field."""


def _need(cond: bool, where: str, what: str) -> None:
    if not cond:
        raise ReportDataError(f"html report: {where}: {what}")


def _finite_or_none(v, where: str):
    if v is None:
        return None
    _need(isinstance(v, (int, float)) and not isinstance(v, bool), where, f"expected a number or null, got {v!r}")
    return float(v) if math.isfinite(v) else None


def validate(out_dir: Path, data: dict) -> dict:
    """Checks `data` against the shape above (and that every image exists); returns a copy with
    non-finite numbers as null (JSON has no NaN)."""
    out_dir = Path(out_dir)
    _need(isinstance(data, dict), "data", "expected a dict")
    missing = []

    def path(p, where):
        _need(isinstance(p, str) and p and not p.startswith(("/", "\\")) and ".." not in Path(p).parts,
              where, f"expected a path relative to the output folder, got {p!r}")
        if not (out_dir / p).is_file():
            missing.append(f"{where} = {p}")
        return p

    clean = {"title": str(data.get("title", "TAA study")), "profile": str(data.get("profile", "")),
             "source": str(data.get("source", "")),
             "resolution": {}, "scenes": {}, "tables": {}, "findings": [], "missed": {}}
    findings = data.get("findings") or []
    _need(isinstance(findings, list) and all(isinstance(x, str) for x in findings), "findings",
          "expected a list of sentences")
    clean["findings"] = list(findings)
    clean["overview"] = None if data.get("overview") is None else path(data["overview"], "overview")
    missed = data.get("missed") or {}
    _need(isinstance(missed, dict) and all(isinstance(v, list) for v in missed.values()), "missed",
          "expected a dict scene -> [targets missed]")
    clean["missed"] = {str(k): [str(x) for x in v] for k, v in missed.items()}
    for scene, wh in (data.get("resolution") or {}).items():
        _need(isinstance(wh, (list, tuple)) and len(wh) == 2 and all(isinstance(v, int) and v > 0 for v in wh),
              f"resolution.{scene}", f"expected [width, height], got {wh!r}")
        clean["resolution"][scene] = list(wh)
    scenes = data.get("scenes") or {}
    _need(isinstance(scenes, dict), "scenes", "expected a dict scene -> tests")
    for scene, sd in scenes.items():
        w = f"scenes.{scene}"
        _need(isinstance(sd, dict), w, "expected a dict")
        agree = sd.get("agreement")
        _need(agree is None or isinstance(agree, dict), f"{w}.agreement", "expected a dict or null")
        cs = {"agreement": None if agree is None else {str(k): (_finite_or_none(v, f"{w}.agreement.{k}")
                                                                if isinstance(v, (int, float)) and not isinstance(v, bool)
                                                                else v) for k, v in agree.items()},
              "reference_bound": str(sd.get("reference_bound") or ""), "static": {}, "ghosting": {},
              "plots": [path(p, f"{w}.plots[{i}]") for i, p in enumerate(sd.get("plots") or [])]}
        for proto, pd in (sd.get("static") or {}).items():
            wp = f"{w}.static.{proto}"
            _need(isinstance(pd, dict) and isinstance(pd.get("techniques"), dict), wp,
                  "expected {'reference': path, 'techniques': {label: ...}}")
            _need(isinstance(pd.get("maps_note", ""), str), f"{wp}.maps_note", "expected a sentence")
            cp = {"reference": path(pd.get("reference"), f"{wp}.reference"), "techniques": {},
                  "maps_note": pd.get("maps_note", "")}
            for label, td in pd["techniques"].items():
                wt = f"{wp}.techniques.{label}"
                _need(isinstance(td, dict), wt, "expected a dict")
                cp["techniques"][label] = {
                    "image": path(td.get("image"), f"{wt}.image"),
                    "ssim_map": None if td.get("ssim_map") is None else path(td["ssim_map"], f"{wt}.ssim_map"),
                    "flip_map": None if td.get("flip_map") is None else path(td["flip_map"], f"{wt}.flip_map"),
                    "metrics": {m: _finite_or_none(v, f"{wt}.metrics.{m}") for m, v in (td.get("metrics") or {}).items()}}
            cs["static"][proto] = cp
        for proto, gd in (sd.get("ghosting") or {}).items():
            wg = f"{w}.ghosting.{proto}"
            _need(isinstance(gd, dict), wg, "expected a dict")
            frames = gd.get("frames")
            _need(isinstance(frames, list) and frames and all(isinstance(f, int) for f in frames), f"{wg}.frames",
                  f"expected a non-empty list of frame ids, got {frames!r}")
            n = len(frames)
            refs = gd.get("reference")
            _need(isinstance(refs, list) and len(refs) == n, f"{wg}.reference",
                  f"expected {n} paths (one per frame), got {refs if not isinstance(refs, list) else len(refs)}")
            cg = {"frames": frames, "reference": [path(p, f"{wg}.reference[{i}]") for i, p in enumerate(refs)],
                  "techniques": {}}
            for label, td in (gd.get("techniques") or {}).items():
                wt = f"{wg}.techniques.{label}"
                imgs = td.get("images") if isinstance(td, dict) else None
                _need(isinstance(imgs, list) and len(imgs) == n, f"{wt}.images", f"expected {n} paths (one per frame)")
                metrics = {}
                for m, vals in (td.get("metrics") or {}).items():
                    _need(isinstance(vals, list) and len(vals) == n, f"{wt}.metrics.{m}",
                          f"expected {n} values (one per frame)")
                    metrics[m] = [_finite_or_none(v, f"{wt}.metrics.{m}[{i}]") for i, v in enumerate(vals)]
                cg["techniques"][label] = {"images": [path(p, f"{wt}.images[{i}]") for i, p in enumerate(imgs)],
                                           "metrics": metrics}
            cs["ghosting"][proto] = cg
        if scene not in clean["resolution"]:
            raise ReportDataError(f"html report: resolution.{scene}: missing (every scene needs [width, height])")
        clean["scenes"][scene] = cs
    for stem, td in (data.get("tables") or {}).items():
        wt = f"tables.{stem}"
        _need(isinstance(td, dict) and isinstance(td.get("header"), list) and isinstance(td.get("rows"), list),
              wt, "expected {'title', 'header': [...], 'rows': [[...]]}")
        ncol = len(td["header"])
        for i, r in enumerate(td["rows"]):
            _need(isinstance(r, list) and len(r) == ncol, f"{wt}.rows[{i}]", f"expected {ncol} cells")
        links = []
        for i, link in enumerate(td.get("links") or []):
            _need(isinstance(link, (list, tuple)) and len(link) == 3 and isinstance(link[0], int)
                  and isinstance(link[1], int) and 0 <= link[0] < len(td["rows"]) and 0 <= link[1] < ncol,
                  f"{wt}.links[{i}]", f"expected [row, column, path] inside the table, got {link!r}")
            links.append([link[0], link[1], path(link[2], f"{wt}.links[{i}]")])
        clean["tables"][stem] = {"title": str(td.get("title", stem)), "note": str(td.get("note") or ""),
                                 "header": [str(h) for h in td["header"]],
                                 "rows": [[str(c) for c in r] for r in td["rows"]], "links": links}
    if missing:
        raise ReportDataError(f"html report: {len(missing)} image(s) missing under {out_dir}: "
                              + "; ".join(missing[:5]) + (" ..." if len(missing) > 5 else ""))
    return clean


def _table_order(tables: dict) -> list[str]:
    first = [t for t in TABLE_ORDER if t in tables]
    return first + [t for t in tables if t not in first]


def viewer_model(data: dict) -> list[dict]:
    """What the page's script gets: one entry per viewer, its layers as a list (the reference
    first), so that no order rests on a JSON object's keys."""
    out = []
    for scene, sd in data["scenes"].items():
        size = data["resolution"].get(scene)
        for proto, pd in sd["static"].items():
            layers = [{"label": "Reference", "images": [pd["reference"]], "ssim": None, "flip": None, "metrics": {}}]
            layers += [{"label": label, "images": [t["image"]], "ssim": t["ssim_map"], "flip": t["flip_map"],
                        "metrics": t["metrics"]} for label, t in pd["techniques"].items()]
            out.append({"id": f"v-{slug(scene)}-{slug(proto)}", "scene": scene, "kind": "static", "proto": proto,
                        "size": size, "frames": [0], "layers": layers})
        for proto, gd in sd["ghosting"].items():
            layers = [{"label": "Reference", "images": gd["reference"], "ssim": None, "flip": None, "metrics": {}}]
            layers += [{"label": label, "images": t["images"], "ssim": None, "flip": None, "metrics": t["metrics"]}
                       for label, t in gd["techniques"].items()]
            out.append({"id": f"v-{slug(scene)}-{slug(proto)}", "scene": scene, "kind": "ghosting", "proto": proto,
                        "size": size, "frames": gd["frames"], "layers": layers})
    ids = [v["id"] for v in out]
    _need(len(set(ids)) == len(ids), "scenes", f"two viewers share an id (scene or protocol names that differ "
                                               f"only in punctuation): {sorted({i for i in ids if ids.count(i) > 1})}")
    return out


def render(data: dict) -> str:
    """The page for validated data."""
    import jinja2
    env = jinja2.Environment(loader=jinja2.PackageLoader("study.reporting", "templates"), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.policies["json.dumps_kwargs"] = {"sort_keys": False, "allow_nan": False}
    src = lambda name: env.loader.get_source(env, name)[0]   # noqa: E731 — raw files, not templates
    links = {stem: {(r, c): p for r, c, p in t["links"]} for stem, t in data["tables"].items()}
    return env.get_template("report.html.j2").render(
        data=data, model={"viewers": viewer_model(data)}, links=links, table_order=_table_order(data["tables"]),
        keys_help=KEYS_HELP, script=src("report.js"), style=src("report.css"), slug=slug,
        summary_tables=[t for t in SUMMARY_TABLES if t in data["tables"]], agreement_text=agreement_text,
        verdict_columns=VERDICT_COLUMNS)


def agreement_text(agree: dict | None) -> str:
    """A scene's agreement in one line (study.reporting.findings_text), or its note as collected."""
    from study.reporting.findings_text import agreement_line
    if not agree:
        return ""
    needed = ("agreement_psnr_db", "raster_samples", "reference_se_bound_lsb", "reference_spp",
              "reference_noise_psnr_db")
    if all(isinstance(agree.get(k), (int, float)) for k in needed):
        return agreement_line(agree)
    return str(agree.get("note") or "; ".join(f"{k.replace('_', ' ')} {v}" for k, v in agree.items()))


def inputs_of(data: dict) -> dict:
    """What the page is made from: its data (the finished folder's tables and files, collect) and
    this module's code and templates; the page is made again when either changes."""
    import hashlib
    h = hashlib.sha256(Path(__file__).read_bytes())
    for f in sorted((Path(__file__).parent / "templates").iterdir()):
        h.update(f.name.encode() + f.read_bytes())
    blob = json.dumps(data, sort_keys=True, default=str).encode()
    return {"data": hashlib.sha256(blob).hexdigest(), "code": h.hexdigest()}


def page(out_dir: Path, data: dict) -> str:
    """Validate `data` against the folder it names, and render the page."""
    return render(validate(Path(out_dir), data))


def write(out_dir: Path, data: dict) -> Path:
    """Validate `data`, write out_dir/report.html, return its path."""
    from provenance.files import write_text_atomic
    target = Path(out_dir) / "report.html"
    write_text_atomic(target, page(out_dir, data))
    return target


def collect(out_dir: Path) -> dict:
    """`data` for write() from the files of a finished study in out_dir (study.reporting.report_folder)."""
    from study.reporting.report_folder import collect as from_folder
    return from_folder(out_dir)


__all__ = ["write", "render", "validate", "collect", "ReportDataError"]
