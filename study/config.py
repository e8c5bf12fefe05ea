"""What a study run compares: technique configurations and profiles."""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

from .protocols import Protocol


@dataclass(frozen=True)
class TechniqueConfig:
    """A technique as a study names it: a column label, a registry name and parameter overrides."""
    label: str
    name: str
    overrides: tuple = ()          # ((field, value), ...) so the config is hashable

    def make(self):
        import taa_impl
        return taa_impl.make(self.name, **dict(self.overrides))

    def key_data(self) -> dict:
        """What identifies this technique's output: registry name, effective parameters, and the
        class whose code (and, transitively, the code it uses) produced it (see provenance)."""
        tech = self.make()
        params = dataclasses.asdict(tech.params) if dataclasses.is_dataclass(tech.params) else repr(tech.params)
        return {"name": self.name, "params": params, "class": f"{type(tech).__module__}.{type(tech).__qualname__}"}

    def code(self) -> type:
        return type(self.make())

    @classmethod
    def parse(cls, text: str) -> "TechniqueConfig":
        """'name' or 'label=name:field=value,field=value' (values parsed as JSON when they can be)."""
        label, _, rest = text.partition("=") if "=" in text.split(":")[0] else ("", "", text)
        name, _, params = rest.partition(":")
        overrides = []
        for item in filter(None, params.split(",")):
            k, eq, v = item.partition("=")
            if not eq:
                raise ValueError(f"technique {text!r}: override {item!r} is not field=value")
            try:
                val = json.loads(v)
            except json.JSONDecodeError:
                val = v
            overrides.append((k, tuple(val) if isinstance(val, list) else val))
        return cls(label or text, name, tuple(overrides))


# The thesis's columns (No AA | FXAA | SMAA | Uncharted | Improved), then the other source
# documents' techniques and an accumulation buffer.
DEFAULT_TECHNIQUES = (
    TechniqueConfig("No AA", "noaa"),
    TechniqueConfig("FXAA", "fxaa"),
    TechniqueConfig("SMAA", "smaa"),
    TechniqueConfig("Uncharted", "taa_baseline"),
    TechniqueConfig("Improved", "taa_improved"),
    # The thesis sharpens both TAAs' output; measured here the sharpen costs the improved TAA
    # about 11 dB, so the same TAA without it is shown beside it.
    TechniqueConfig("Improved, no sharpen", "taa_improved", (("sharpen", "none"),)),
    TechniqueConfig("Sparse SS", "taa_sparse"),
    TechniqueConfig("Ferrando", "taa_ferrando_text"),
    TechniqueConfig("SSAA 16x", "accumulation", (("samples", 16),)),
)

# Sparse supersampling's threshold mu against its cost (seed 002 chose 0.2 as the trade-off).
SPARSE_SWEEP = tuple(TechniqueConfig(f"Sparse mu={mu}", "taa_sparse", (("mu", mu),))
                     for mu in (0.05, 0.1, 0.2, 0.4, 0.8))


# Log-spaced history lengths of the convergence study (one 256-frame run judged at each).
CHECKPOINTS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
THESIS_HISTORY = 16          # the thesis keeps frame 16 after a reset (spec section 10)
# k = 0.979 weighs the first frame below 1 % after ln 0.01 / ln k = 217 frames (spec section 13).
CONVERGED_HISTORY = 256
CONVERGED_WARMUP = 224       # a multiple of the jitter period, so warm-up frames repeat 16 raster frames


@dataclass(frozen=True)
class Profile:
    name: str
    use_full_resolution: bool
    static: Protocol
    ghosting: tuple = ()                  # ghosting protocols (cold = the thesis's, warm = converged)
    target_noise_db: float = 60.0         # reference convergence target
    ghosting_techniques_skip: tuple = ("accumulation",)   # N sub-frames per frame: too slow for sequences
    sweep_scenes: tuple = ("sphere_ghosting", "disocclusion")  # where the sparse-supersampling mu sweep runs
    agreement_samples: int = 64

    @property
    def static_views(self) -> dict[str, int]:
        """Labelled static protocols read from the one static run: label -> history length."""
        return {f"thesis ({THESIS_HISTORY} frames, cold)": THESIS_HISTORY,
                f"converged ({self.static.history} frames)": self.static.history}


def _profile(name: str, full: bool, ghost_frames: int, **kw) -> Profile:
    return Profile(name, full, Protocol("static", "static", history=CONVERGED_HISTORY, checkpoints=CHECKPOINTS),
                   (Protocol("ghosting", "ghosting", frames=ghost_frames, warmup=0),
                    Protocol("ghosting_warm", "ghosting", frames=ghost_frames, warmup=CONVERGED_WARMUP)), **kw)


PROFILES = {
    "quick": _profile("quick", False, 24),
    "full": _profile("full", True, 100, ghosting_techniques_skip=(), agreement_samples=256),
}


def available(configs) -> tuple[list, list]:
    """(configs whose technique exists, names that do not exist yet)."""
    import taa_impl
    ok, missing = [], []
    for c in configs:
        (ok if c.name in taa_impl.TECHNIQUES else missing).append(c)
    return ok, missing
