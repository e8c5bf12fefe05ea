"""The texture LOD bias of a study column's raster frames (docs/method.md, "Texture filtering")."""
from __future__ import annotations

import math


def lod_bias(explicit: float | None, inputs) -> float:
    """The column's own bias (`explicit`), else log2(render / display) - 1 for an upscaler (FSR 2's
    documented rule: the textures of the output's resolution, and one level sharper for the detail
    accumulated over frames) and 0 for every other technique (a TAA at native resolution samples
    textures as the scene was authored). `inputs`: the technique's taa_impl.contract.Inputs."""
    if explicit is not None:
        return float(explicit)
    return math.log2(float(inputs.render_scale)) - 1.0 if inputs.upsamples else 0.0
