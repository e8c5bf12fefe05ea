"""The perceptual video metric's settings (a study file's [video]; study.metrics.video computes it,
study.engine.video_task runs it). Their defaults: study.config.defaults.VIDEO."""
from __future__ import annotations

from dataclasses import dataclass

from . import defaults as D


@dataclass(frozen=True)
class Video:
    metric: str = D.VIDEO["metric"]              # 'cvvdp' | 'none'
    display: str = D.VIDEO["display"]            # a cvvdp display model
    fps: float = D.VIDEO["fps"]                  # the frame rate a ghosting test is played at
    tests: tuple = D.VIDEO["tests"]              # 'ghosting' (every ghosting protocol) and/or 'static'
    scenes: tuple = ()                           # scene names; () = every scene of those tests
    techniques: tuple = ()                       # column labels or registry names; () = every column

    def __post_init__(self):
        for f in ("tests", "scenes", "techniques"):
            object.__setattr__(self, f, tuple(getattr(self, f)))

    @property
    def on(self) -> bool:
        return self.metric != "none"

    def judges(self, kind: str, scene: str, config) -> bool:
        """Whether a test of this kind ('static' | 'ghosting') on this scene judges the column."""
        return (self.on and kind in self.tests and (not self.scenes or scene in self.scenes)
                and (not self.techniques or config.label in self.techniques or config.name in self.techniques))

    def key_data(self) -> dict:
        """What a JOD figure depends on besides its frames (the metric's code is keyed apart)."""
        return {"metric": self.metric, "display": self.display, "fps": float(self.fps)}
