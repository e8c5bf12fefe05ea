"""The HTML report's data read back from a finished study folder alone (its tables, images, maps and
manifest): study.reporting.html_report's `data`, without per-frame ghosting images or metrics."""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from study.reporting.encode import slug
from study.reporting.tables import technique_columns


def _number(cell: str):
    """The leading number of a table cell ('42.1', '42.1 / 0.99', '∞'), or None."""
    cell = cell.strip()
    if cell.startswith("∞"):
        return None
    m = re.match(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?", cell)
    return float(m.group()) if m else None


def _read_csv(p: Path) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(p.read_text().splitlines()))
    return (rows[0], rows[1:]) if rows else ([], [])


def _md_title_note(p: Path) -> tuple[str, str]:
    """Title and note of a table's Markdown file (study.reporting.tables.Table.markdown's layout)."""
    if not p.exists():
        return p.stem, ""
    lines = p.read_text().splitlines()
    title = lines[0].lstrip("# ").strip() if lines else p.stem
    note = lines[2].strip() if len(lines) > 2 and not lines[2].startswith("|") else ""
    return title, note


def static_scenes(listed) -> list[str]:
    """The scenes of a study's static test, from the file names it lists (images/static_<scene>_reference.png
    with tables/static_<scene>.csv)."""
    names = sorted({rel[len("images/static_"):-len("_reference.png")] for rel in listed
                    if rel.startswith("images/static_") and rel.endswith("_reference.png")})
    # "static_converged_X_reference" reads as scene "converged_X" of stem "static" too: where X is a
    # scene of its own, it is X's converged protocol.
    return [s for s in names if f"tables/static_{s}.csv" in listed
            and not (s.startswith("converged_") and s[len("converged_"):] in names)]


def collect(out_dir: Path) -> dict:
    """`data` for write() from the files of a finished study in out_dir (see the module docstring)."""
    from PIL import Image

    from study.reporting.tables import METRIC_LABELS
    out_dir = Path(out_dir)
    manifest = json.loads((out_dir / "manifest.json").read_text())
    summary, listed = manifest.get("summary", {}), manifest.get("artefacts", {})
    metric_key = {v: k for k, v in METRIC_LABELS.items()}
    have = lambda rel: rel in listed and (out_dir / rel).is_file()   # noqa: E731

    stems = ("static", "static_converged")
    scene_names = [s for s in static_scenes(listed) if have(f"tables/static_{s}.csv")]
    data = {"title": f"TAA study ({summary.get('profile', '?')} profile)", "profile": summary.get("profile", ""),
            "resolution": {}, "scenes": {}, "tables": {}}
    conv_rows = {}
    if have("tables/reference_convergence.csv"):
        header, rows = _read_csv(out_dir / "tables/reference_convergence.csv")
        conv_rows = {r[0]: dict(zip(header, r)) for r in rows}
        _, conv_note = _md_title_note(out_dir / "tables/reference_convergence.md")
    images_of = {}       # (stem, scene, label) -> image path
    for scene in scene_names:
        sd = {"agreement": None, "reference_bound": "", "static": {}, "ghosting": {}}
        for stem in stems:
            table = f"tables/{stem}_{scene}.csv"
            ref = f"images/{stem}_{scene}_reference.png"
            if not (have(table) and have(ref)):
                continue
            header, rows = _read_csv(out_dir / table)
            labels = technique_columns(header)
            techniques = {}
            for li, label in enumerate(labels, start=1):
                base = f"{stem}_{scene}_{slug(label)}"
                img = f"images/{base}.png"
                if not have(img):
                    continue
                images_of[(stem, scene, label)] = img
                for kind in ("ssim", "flip"):
                    if have(f"maps/{base}_{kind}.png"):
                        images_of[(stem, scene, label, kind)] = f"maps/{base}_{kind}.png"
                techniques[label] = {
                    "image": img,
                    "ssim_map": f"maps/{base}_ssim.png" if have(f"maps/{base}_ssim.png") else None,
                    "flip_map": f"maps/{base}_flip.png" if have(f"maps/{base}_flip.png") else None,
                    "metrics": {metric_key.get(r[0], r[0]): _number(r[li]) for r in rows if r and r[0]}}
            title, note = _md_title_note(out_dir / f"tables/{stem}_{scene}.md")
            m = re.fullmatch(rf"Static test, (.+): {re.escape(scene)}", title)
            sd["static"][m.group(1) if m else stem] = {"reference": ref, "techniques": techniques}
            if have(f"maps/{stem}_{scene}_marked.json"):      # what the maps' painted pixels mean (map_noise)
                marked = json.loads((out_dir / f"maps/{stem}_{scene}_marked.json").read_text())
                sd["static"][m.group(1) if m else stem]["maps_note"] = str(marked.get("note", ""))
            m = re.search(r"Reference agreement.*", note)
            if m and sd["agreement"] is None:
                sd["agreement"] = {"note": m.group().strip()}
        if scene in conv_rows:
            r = conv_rows[scene]
            sd["reference_bound"] = "; ".join(f"{k}: {v}" for k, v in r.items() if k != "scene") + \
                                    (f". {conv_note}" if conv_note else "")
        sd["plots"] = sorted(rel for rel in listed if rel.startswith("plots/") and rel.endswith(f"_{scene}.png")
                             and have(rel))
        with Image.open(out_dir / next(iter(sd["static"].values()))["reference"]) as im:
            data["resolution"][scene] = list(im.size)
        data["scenes"][scene] = sd

    if have("plots/overview.png"):
        data["overview"] = "plots/overview.png"
    record = json.loads((out_dir / "tables/findings.json").read_text()) if have("tables/findings.json") else None
    if record is not None:
        from study.reporting import findings_text
        data["findings"] = findings_text.summary(record)
    from study.reporting.source import study_line     # the first screen's first line: which study
    res = (record or {}).get("resolutions") or sorted({f"{w}x{h}" for w, h in data["resolution"].values()})
    data["source"] = "From " + study_line(summary, res)
    for rel in sorted(listed):
        if not (rel.startswith("tables/") and rel.endswith(".csv")) or not have(rel):
            continue
        stem = Path(rel).stem
        header, rows = _read_csv(out_dir / rel)
        title, note = _md_title_note(out_dir / rel.replace(".csv", ".md"))
        data["tables"][stem] = {"title": title, "note": note, "header": header, "rows": rows,
                                "links": _links(stem, header, rows, images_of, scene_names)}
    return data


def _links(stem: str, header: list[str], rows: list[list[str]], images_of: dict, scenes: list[str]) -> list:
    """The images behind a table's cells, for the tables whose rows name a scene and a technique."""
    links = []
    col = {h: i for i, h in enumerate(header)}
    converged = lambda scene, label: images_of.get(("static_converged", scene, label)) or \
        images_of.get(("static", scene, label))     # noqa: E731
    if stem == "headline":
        seen = {}
        for r, row in enumerate(rows):
            scene = row[0]
            nth = seen.get(scene, 0)            # the protocols come in the static views' order
            seen[scene] = nth + 1
            pstem = ("static", "static_converged")[min(nth, 1)]
            for c, label in enumerate(technique_columns(header, first=2), start=2):
                if (pstem, scene, label) in images_of:
                    links.append([r, c, images_of[(pstem, scene, label)]])
    elif stem in ("speed_error", "history_convergence"):
        for r, row in enumerate(rows):
            scene, label = row[0], row[1]
            if converged(scene, label):
                links.append([r, 1, converged(scene, label)])
            if stem == "history_convergence" and ("static", scene, label) in images_of and len(row) > 2:
                links.append([r, 2, images_of[("static", scene, label)]])
            if stem == "history_convergence" and converged(scene, label) and len(row) > 3:
                links.append([r, 3, converged(scene, label)])
    elif stem == "reproduction":
        for r, row in enumerate(rows):
            scene = row[0].split(" (")[0]
            pstem = "static_converged" if "converged" in row[0] else "static"
            best = row[col.get("our ranking (PSNR)", 2)].split(" > ")[0].strip() if len(row) > 2 else ""
            if (pstem, scene, best) in images_of:
                links.append([r, 2, images_of[(pstem, scene, best)]])
    else:
        for pstem in ("static_converged", "static"):      # static_<scene> and static_converged_<scene>
            scene = stem[len(pstem) + 1:] if stem.startswith(pstem + "_") else None
            if scene in scenes:
                for c, label in enumerate(technique_columns(header), start=1):
                    for r, row in enumerate(rows):
                        # the SSIM and FLIP rows open the maps behind them, the others the image
                        kind = "ssim" if row[0] == "SSIM" else "flip" if row[0].startswith("FLIP") else None
                        p = images_of.get((pstem, scene, label, kind)) or images_of.get((pstem, scene, label))
                        if p:
                            links.append([r, c, p])
                break
    return links
