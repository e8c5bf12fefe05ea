"""The study's task kinds as data: one frozen record per kind, its inputs as named fields, and a
planned Task (key, spec, dependencies). Calling a spec runs its task function on those fields and
nothing else (a pure call on data, as Dask runs it), so the planner, the executors, the disk
check (study.engine.disk) and the cost estimate (study.engine.estimate) read what a task will do by
name. The task functions keep their positional signatures: their modules' source is part of
their keys (study.engine.plan.CODE), and this module is not.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from study.engine import agreement as A
from study.engine import judge as J
from study.engine import reference_task as R
from study.engine import run_task as RT
from study.engine import video_task as V
from study.engine.tasks import Context


@dataclass(frozen=True)
class ReferenceSpec:
    """One (scene, frame) rendered to `settings` (study.engine.reference_task)."""
    kind: ClassVar[str] = "reference"
    ctx: Context
    scene: str                    # what load_scene takes (built-in name or file path)
    t: int                        # scene time
    width: int
    height: int
    settings: dict                # the reference's settings (references.ReferenceCache.get)

    def __call__(self) -> dict:
        return R.reference_task(self.ctx, self.scene, self.t, self.width, self.height, dict(self.settings))


@dataclass(frozen=True)
class RunSpec:
    """Techniques that share raster frames run over one protocol on one scene (study.engine.run_task)."""
    kind: ClassVar[str] = "run"
    ctx: Context
    scene: str
    width: int
    height: int
    protocol: object              # study.config.protocols.Protocol
    configs: list                 # the TechniqueConfigs it makes
    keys: dict                    # label -> run key
    folders: dict                 # label -> run folder
    display_settings: dict        # the references display transforms come from
    feeds: dict                   # label -> [(metrics folder, key)] the run is judged into
    judge: list | None = None     # the metrics items judged as the runs are made (run_task lists its fields)

    def __call__(self) -> dict:
        return RT.run_task(self.ctx, self.scene, self.width, self.height, self.protocol, self.configs,
                           self.keys, self.folders, self.display_settings, self.feeds, self.judge)


@dataclass(frozen=True)
class MetricsSpec:
    """A test's techniques judged against their references (study.engine.judge)."""
    kind: ClassVar[str] = "metrics"
    ctx: Context
    scene: str
    width: int
    height: int
    items: list                   # one dict per technique (judge.metrics_task lists its fields)
    ref_settings: dict            # scene time -> its reference's settings
    display_settings: dict

    def __call__(self) -> dict:
        return J.metrics_task(self.ctx, self.scene, self.width, self.height, self.items, self.ref_settings,
                              self.display_settings)


@dataclass(frozen=True)
class AgreementSpec:
    """The raster against frame 0's reference (study.engine.agreement)."""
    kind: ClassVar[str] = "agreement"
    ctx: Context
    scene: str
    width: int
    height: int
    samples: int                  # raster frames averaged
    ref_settings: dict
    display_settings: dict
    key: str                      # its record's key
    path: str                     # its record's file

    def __call__(self) -> dict:
        return A.agreement_task(self.ctx, self.scene, self.width, self.height, self.samples, self.ref_settings,
                                self.display_settings, self.key, self.path)


@dataclass(frozen=True)
class VideoSpec:
    """One column's JOD (ColorVideoVDP) against its references (study.engine.video_task)."""
    kind: ClassVar[str] = "video"
    ctx: Context
    scene: str
    width: int
    height: int
    items: list                   # one dict per technique (video_task.video_task lists its fields)
    ref_settings: dict            # scene time -> its reference's settings
    display_settings: dict
    video: dict                   # study.config.video.Video.task_data()
    protocol_kind: str            # static | ghosting

    def __call__(self) -> dict:
        return V.video_task(self.ctx, self.scene, self.width, self.height, self.items, self.ref_settings,
                            self.display_settings, self.video, self.protocol_kind)


SPECS = (ReferenceSpec, RunSpec, MetricsSpec, AgreementSpec, VideoSpec)
Spec = ReferenceSpec | RunSpec | MetricsSpec | AgreementSpec | VideoSpec


@dataclass
class Task:
    """A planned task: its key, what it computes and the tasks it runs after."""
    key: str
    spec: Spec
    deps: tuple = ()
    likely_cached: bool = False   # its artefact's file is there: a cache hit, unless damaged

    @property
    def kind(self) -> str:
        """reference | run | metrics | agreement | video"""
        return self.spec.kind
