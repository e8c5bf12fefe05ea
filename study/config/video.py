"""The perceptual video metric's settings (a study file's [video]; study.metrics.video computes it,
study.engine.video_task runs it). Their defaults: study.config.defaults.VIDEO."""
from __future__ import annotations

import importlib.util
import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from . import defaults as D


@lru_cache(maxsize=1)
def display_models() -> dict:
    """cvvdp's display models (name -> description), read from the package's data without
    importing it (its import loads torch: 10-25 s)."""
    spec = importlib.util.find_spec("pycvvdp")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the cvvdp package is not installed (scripts/setup.sh installs it)")
    path = Path(list(spec.submodule_search_locations)[0]) / "vvdp_data" / "display_models.json"
    return {k: v.get("name", k) for k, v in json.loads(path.read_text()).items()}


@dataclass(frozen=True)
class Video:
    metric: str = D.VIDEO["metric"]              # 'cvvdp' | 'none'
    display: str = D.VIDEO["display"]            # a cvvdp display model
    fps: float = D.VIDEO["fps"]                  # the frame rate a ghosting test is played at
    tests: tuple = D.VIDEO["tests"]              # 'ghosting' (every ghosting protocol) and/or 'static'
    protocols: tuple = ()                        # protocol names; () = every protocol of those tests
    scenes: tuple = ()                           # scene names; () = every scene of those tests
    techniques: tuple = ()                       # column labels or registry names; () = every column
    device: str = D.VIDEO["device"]              # torch's: 'auto' (CUDA where torch sees one) | 'cpu' | 'cuda'

    def __post_init__(self):
        for f in ("tests", "protocols", "scenes", "techniques"):
            object.__setattr__(self, f, tuple(getattr(self, f)))

    @property
    def on(self) -> bool:
        return self.metric != "none"

    def judges(self, kind: str, scene: str, config, protocol: str | None = None) -> bool:
        """Whether a test of this kind ('static' | 'ghosting'; its protocol's name `protocol`) on
        this scene judges the column."""
        return (self.on and kind in self.tests and (not self.protocols or protocol in self.protocols)
                and (not self.scenes or scene in self.scenes)
                and (not self.techniques or config.label in self.techniques or config.name in self.techniques))

    def task_data(self) -> dict:
        """What a video task is given: key_data and the device it runs on (which keys nothing: the
        same metric, on another processor)."""
        return {**self.key_data(), "device": self.device}

    def key_data(self) -> dict:
        """What a JOD figure depends on besides its frames (the metric's code is keyed apart)."""
        return {"metric": self.metric, "display": self.display, "fps": float(self.fps)}
