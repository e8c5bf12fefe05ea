"""The texture LOD bias of a study column's raster frames (docs/method.md, "Texture filtering")."""
from __future__ import annotations

import math

MIN_LOD_BIAS = -4.0   # a study's default limit (study files: min_lod_bias; the command line: this)


def lod_bias(explicit: float | None, inputs) -> float:
    """The column's own bias (`explicit`), else for an upscaler log2(render / display), the
    output's texel density, and one level sharper, - 1, where it accumulates samples over frames
    (FSR 2's documented rule); a spatial upscaler has no frames to add detail from, so it stays at
    the density. 0 for every other technique (a TAA at native resolution samples textures as the
    scene was authored). `inputs`: the technique's taa_impl.contract.Inputs."""
    if explicit is not None:
        return float(explicit)
    if not inputs.upsamples:
        return 0.0
    return math.log2(float(inputs.render_scale)) - (1.0 if inputs.sampling == "sequence" else 0.0)
