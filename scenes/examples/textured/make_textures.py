"""Writes the two PNG textures of these example scenes (run once; the PNGs are committed)."""
from pathlib import Path

import numpy as np
from PIL import Image

here = Path(__file__).resolve().parent

# thin bright lines on a dark field: a 1-texel grid every 16 texels of a 256-texel tile
lines = np.full((256, 256), 10, np.uint8)
lines[::16, :] = 250
lines[:, ::16] = 250
Image.fromarray(lines).convert("RGB").save(here / "thin_lines.png", optimize=True)

# an alpha-tested leaf: serrated outline and vein cut-outs, binary, 256 texels
n = 256
v, u = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n, indexing="ij")
half = 0.46 * np.sin(np.pi * v) ** 1.2 - 0.02 * (np.sin(60 * np.pi * v) > 0.3)
inside = np.abs(u - 0.5) < half
veins = (np.abs(u - 0.5) < 0.006) | ((np.abs(np.abs(u - 0.5) - (v - 0.15) * 0.6) < 0.004) & (v > 0.2))
leaf = (inside & ~veins).astype(np.uint8) * 255
Image.fromarray(leaf[::-1]).convert("RGB").save(here / "leaf_alpha.png", optimize=True)
