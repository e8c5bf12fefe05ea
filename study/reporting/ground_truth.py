"""The thesis's ground truth against ours: every technique of a static test judged also against
a 128-sample Halton accumulation of our own raster (the thesis's ground truth; taa_impl's
`accumulation` with its default 128 samples), as the thesis judged it: PSNR of the 8-bit display
images, under the display transform the study's figures use.

`figures(report, views, label)` -> {"<scene>|<view>": {technique label: PSNR}} from the runs' kept
frames (each view's judged frame is kept: study.engine.plan), cached in tables/ground_truth.json
by the runs' keys, so a study that changed nothing reads no frame. `table(...)` compares each
ranking with the path-traced one.
"""
from __future__ import annotations

import json
import math

import numpy as np

THESIS_GROUND_TRUTH = "accumulation"      # registry name; its default params are the thesis's 128 samples


def label_of(configs) -> str | None:
    """The label of the config that is the thesis's ground truth (accumulation, default params)."""
    return next((c.label for c in configs if c.is_default(THESIS_GROUND_TRUTH)), None)


def _psnr(a8: np.ndarray, b8: np.ndarray) -> float:
    mse = float(np.mean((a8.astype(np.float64) - b8.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def figures(report, views: dict, references: dict, label: str | None) -> dict:
    if label is None:
        return {}
    todo = [(vl, r) for vl, rs in views.items() for r in rs if label in r.artefacts]
    inputs = {f"{r.scene}|{vl}": {l: [a["run_key"], a["frame"]] for l, a in r.artefacts.items()} for vl, r in todo}

    def compute() -> str:
        out = {}
        for vl, r in todo:
            disp = report.display(r.scene, 0, r.width, r.height, references[r.scene])
            a = r.artefacts[label]
            gt8 = report.artefacts.frame_8bit(a, a["frame"], disp)
            out[f"{r.scene}|{vl}"] = {l: _psnr(report.artefacts.frame_8bit(x, x["frame"], disp), gt8)
                                      for l, x in r.artefacts.items() if l != label}
        return json.dumps(out, sort_keys=True)
    report._file("tables/ground_truth.json", compute, inputs)
    data = json.loads((report.out / "tables/ground_truth.json").read_text())
    return {k: {l: (math.inf if v is None else v) for l, v in per.items()} for k, per in data.items()}
