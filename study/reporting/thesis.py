"""The thesis's published figures (thesis_figures.toml beside this file), read once."""
from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path

FIGURES_FILE = Path(__file__).resolve().parent / "thesis_figures.toml"


@lru_cache(maxsize=None)
def figures() -> dict:
    data = tomllib.loads(FIGURES_FILE.read_text(encoding="utf-8"))
    n = len(data["columns"])
    for table in ("static_psnr", "static_ssim"):
        bad = [s for s, v in data[table].items() if len(v) != n]
        if bad:
            raise ValueError(f"{FIGURES_FILE}: [{table}] {bad}: need {n} values ({', '.join(data['columns'])})")
    return data


_F = figures()
THESIS_COLUMNS = tuple(_F["columns"])
THESIS_STATIC_PSNR = {s: tuple(v) for s, v in _F["static_psnr"].items()}
THESIS_STATIC_SSIM = {s: tuple(v) for s, v in _F["static_ssim"].items()}
THESIS_GHOST_MSE = {s: tuple(v) for s, v in _F["ghosting_mse"].items() if isinstance(v, list)}
THESIS_GHOST_FRAMES = int(_F["ghosting_mse"]["ghosting_frames"])
THESIS_SHARPEN = {k: (list(v) if isinstance(v, list) else v) for k, v in _F["sharpen_test"].items()}
THESIS_TIMINGS_MS = {k: tuple(v) for k, v in _F["timings_ms"].items()}
