"""One static protocol's table, its display images and its SSIM/FLIP maps, the maps painted where the
reference's noise exceeds their colour step (study.reporting.map_noise). A mixin of
study.reporting.report.Report (its `_file`, `_table`, `display` and `artefacts`)."""
from __future__ import annotations

import json

import numpy as np

from study.reporting import map_noise
from study.reporting.encode import exr_bytes, magma, png, slug
from study.reporting.findings_text import floor_note, precision_note
from study.reporting.tables import thesis_layout

STATIC_METRICS = ["mse", "rmsd", "psnr", "snr", "ssim", "flip_ldr", "flip_hdr", "relmse_hdr", "ms"]


class Static:
    def static(self, res, agree: dict | None, ref, stem: str) -> None:
        """One static protocol's table, display images and maps (res: a view of the static run)."""
        n = res.frames[-1]
        results = {l: {**res.per_frame[l][n], "ms": res.ms[l]} for l in res.per_frame}
        inputs = {"runs": {l: a["run_key"] for l, a in res.artefacts.items()},
                  "metrics": {l: a["metrics_key"] for l, a in res.artefacts.items()},
                  "video": {l: a.get("video_key") for l, a in res.artefacts.items()},
                  "costs": {l: c.get("key") for l, c in res.costs.items()}}
        note = (f"{res.test}: {res.width}x{res.height}, 8-bit display images; ms / frame = raster of the samples "
                f"shaded + resolve (study.engine.costs). " + floor_note(agree) + precision_note(res))
        us = {l: res.uncertainty.get(l, {}).get(n, {}) for l in res.per_frame}
        jod = ["jod"] if any("jod" in v for v in results.values()) else []     # where the study judges it
        table = thesis_layout(f"Static test, {res.test}: {res.scene}", results, STATIC_METRICS + jod,
                              self.improved if self.improved in results else None, note, uncertainty=us)
        self._table(f"{stem}_{res.scene}", table, inputs)
        shown: list = []

        def disp():            # made only for an image to be made again
            if not shown:
                shown.append(self.display(res.scene, 0, res.width, res.height, ref))
            return shown[0]
        self._file(f"images/{stem}_{res.scene}_reference.png", lambda: png(disp().to_8bit(ref.image)),
                   {"reference": ref.key}, parallel=True)
        marked = {}           # kind -> the pixels the reference's noise leaves unresolved (map_noise)
        if any(a["frame"] in a["maps_for"] for a in res.artefacts.values()):
            se = map_noise.reference_se_lsb(ref, disp())
            marked = {k: map_noise.marks(se, k) for k in map_noise.KINDS}
            counts = {k: int(m.sum()) for k, m in marked.items()}
            self._file(f"maps/{stem}_{res.scene}_marked.json", json.dumps(
                {"rule": "reference display SE (worst channel, 8-bit LSB) > threshold", "steps": map_noise.MAP_STEPS,
                 "threshold_lsb": {k: map_noise.threshold_lsb(k) for k in marked}, "marked": counts,
                 "pixels": int(se.size), "se_lsb_p999": float(np.percentile(se, 99.9)),
                 "note": map_noise.note(counts, int(se.size))}, indent=1, sort_keys=True),
                {"reference": ref.key, "thresholds": map_noise.THRESHOLDS, "steps": map_noise.MAP_STEPS})
        mkey = {"reference": ref.key, "thresholds": map_noise.THRESHOLDS, "steps": map_noise.MAP_STEPS,
                "mark": map_noise.MARK_RGB}
        for label, a in res.artefacts.items():
            f = a["frame"]
            key = {"run": a["run_key"], "metrics": a["metrics_key"], "frame": f}
            base = f"{stem}_{res.scene}_{slug(label)}"

            def image(a=a, f=f):
                return png(self.artefacts.frame_8bit(a, f, disp()))
            self._file(f"images/{base}.png", image, key, parallel=True)
            if f not in a["maps_for"]:
                continue
            maps = {}

            def get_maps(a=a, f=f, maps=maps):
                if not maps:
                    maps.update(self.artefacts.maps(a, f))
                return maps
            # made later, on the pool: each bound to this technique's maps, not the loop's last
            # painted where the reference's noise exceeds the map's colour step (study.reporting.map_noise)
            self._file(f"maps/{base}_ssim.png", lambda g=get_maps: png(map_noise.paint(
                np.round(np.clip(g()["ssim"], 0, 1) * 255).astype(np.uint8), marked["ssim"])),
                {**key, "marks": mkey}, parallel=True)
            self._file(f"maps/{base}_flip.png", lambda g=get_maps: png(map_noise.paint(
                magma(g()["flip_ldr"]), marked["flip"])), {**key, "marks": mkey}, parallel=True)
            self._file(f"maps/{base}.exr", lambda g=get_maps: exr_bytes(g()), key, parallel=True)
