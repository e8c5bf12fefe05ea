"""What a study run compares: technique configurations and profiles."""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def source_hash(*globs: str) -> str:
    """Hash of source files, so an artefact is recomputed when the code that made it changes."""
    h = hashlib.sha256()
    for pattern in globs:
        for p in sorted(ROOT.glob(pattern)):
            h.update(p.relative_to(ROOT).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:12]


def technique_code_hash(tech) -> str:
    """Hash of the taa_impl modules this technique's code comes from: the modules of its classes
    and, transitively, the taa_impl modules they use. Editing one technique recomputes only it."""
    import inspect
    import sys
    seen: set[str] = set()
    todo = [c.__module__ for c in type(tech).__mro__ if c.__module__.startswith("taa_impl")]
    while todo:
        name = todo.pop()
        if name in seen or name not in sys.modules:
            continue
        seen.add(name)
        for v in vars(sys.modules[name]).values():
            mod = v.__name__ if inspect.ismodule(v) else getattr(v, "__module__", None)
            if isinstance(mod, str) and mod.startswith("taa_impl.") and mod not in seen:
                todo.append(mod)
    h = hashlib.sha256()
    for name in sorted(seen):
        path = Path(sys.modules[name].__file__)
        h.update(name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:12]


def stable_hash(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class TechniqueConfig:
    """A technique as a study names it: a column label, a registry name and parameter overrides."""
    label: str
    name: str
    overrides: tuple = ()          # ((field, value), ...) so the config is hashable

    def make(self):
        import taa_impl
        return taa_impl.make(self.name, **dict(self.overrides))

    def key(self) -> str:
        tech = self.make()
        params = dataclasses.asdict(tech.params) if dataclasses.is_dataclass(tech.params) else repr(tech.params)
        return stable_hash({"name": self.name, "params": params, "code": technique_code_hash(tech)})

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


@dataclass(frozen=True)
class Profile:
    name: str
    use_full_resolution: bool
    ghosting_frames: int           # frames of each ghosting sequence (capped by the scene's own)
    history_frames: int = 16       # static test: frames of TAA history before the kept frame
    target_noise_db: float = 60.0  # reference convergence target
    ghosting_techniques_skip: tuple = ("accumulation",)   # N sub-frames per frame: too slow for sequences
    sweep_scenes: tuple = ("sphere_ghosting", "disocclusion")  # where the sparse-supersampling mu sweep runs


PROFILES = {
    "quick": Profile("quick", False, ghosting_frames=24),
    "full": Profile("full", True, ghosting_frames=100, ghosting_techniques_skip=()),
}


def available(configs) -> tuple[list, list]:
    """(configs whose technique exists, names that do not exist yet)."""
    import taa_impl
    ok, missing = [], []
    for c in configs:
        (ok if c.name in taa_impl.TECHNIQUES else missing).append(c)
    return ok, missing
