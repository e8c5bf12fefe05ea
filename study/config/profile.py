"""Profiles: a whole study as its study file describes it (study.config.studyfile; the built-in
quick and full profiles are such files), and the thesis's columns among its techniques."""
from __future__ import annotations

from dataclasses import dataclass, field

from . import defaults as D
from study.config.protocols import Protocol
from .precision import Precision
from .techniques import TechniqueConfig
from .video import Video

# Sparse supersampling's threshold mu against its cost (Li, Chen, Zhang 2021 chose 0.2 as the trade-off).
SPARSE_SWEEP = tuple(TechniqueConfig(f"Sparse mu={mu}", "taa_sparse", (("mu", mu),))
                     for mu in (0.05, 0.1, 0.2, 0.4, 0.8))

THESIS_HISTORY = D.THESIS_HISTORY

# The sharpen sweep's TAAs: the thesis's two, by their columns' names.
SHARPEN_SWEEP_TAAS = (("Uncharted", "taa_baseline"), ("Improved", "taa_improved"))


def sharpen_sweep_configs(strengths) -> tuple:
    """Both thesis TAAs at each sharpen strength w, labelled 'Uncharted, sharpen w=0.5'."""
    return tuple(TechniqueConfig(f"{role}, sharpen w={w:g}", name, (("sharpen", float(w)),))
                 for role, name in SHARPEN_SWEEP_TAAS for w in strengths)


def sharpen_sweep_point(label: str) -> tuple[str, float] | None:
    """(TAA role, w) of a sharpen sweep column's label, None for any other label."""
    role, sep, rest = label.partition(", sharpen w=")
    if not sep or role not in dict(SHARPEN_SWEEP_TAAS):
        return None
    try:
        return role, float(rest)
    except ValueError:
        return None

# The thesis's columns by what they are: a registry technique with its default parameters.
THESIS_TECHNIQUES = {"No AA": "noaa", "FXAA": "fxaa", "SMAA": "smaa", "Uncharted": "taa_baseline",
                     "Improved": "taa_improved"}


def thesis_roles(configs) -> dict[str, str]:
    """Thesis column -> label of the first config that is that technique with default parameters."""
    out = {}
    for role, name in THESIS_TECHNIQUES.items():
        for c in configs:
            if c.is_default(name):
                out[role] = c.label
                break
    return out


@dataclass(frozen=True)
class SceneGroup:
    """Scenes a study tests on their own terms (a study file's [[scene_groups]]): only `tests`
    (protocol names; () every one) and, when a run has the study's own columns, only `columns`
    (their labels; () every one) then its own `techniques` (TechniqueConfigs these scenes alone get).
    A run given other columns (--techniques, `ab`) tests these scenes with those."""
    name: str
    scenes: tuple                         # scene names, or scene files' paths as the study lists them
    tests: tuple = ()
    columns: tuple = ()
    techniques: tuple = ()

    def holds(self, spec: str, name: str) -> bool:
        """Whether the scene (its spec as the run names it, and its name) is one of the group's."""
        if spec in self.scenes or name in self.scenes:
            return True
        from pathlib import Path
        return spec.endswith((".toml", ".json")) and str(Path(spec).resolve()) in self.scenes

    def runs(self, protocol: str) -> bool:
        """Whether the group's scenes get the test of this protocol (by name)."""
        return not self.tests or protocol in self.tests

    def configs(self, configs, own: bool) -> list:
        """The columns its scenes' tests get from a run's `configs`; `own`: they are the study's own."""
        if not own:
            return list(configs)
        return [c for c in configs if not self.columns or c.label in self.columns] + list(self.techniques)


@dataclass(frozen=True)
class Profile:
    """A whole study as a study file describes it (study.config.studyfile; the built-in profiles are files)."""
    name: str
    resolution: object                    # 'quick' | 'full' (each scene's own) | (w, h)
    static: Protocol
    ghosting: tuple = ()                  # ghosting protocols
    ref_settings: tuple = tuple(D.REFERENCE.items())     # ReferenceCache.get settings
    ghosting_techniques_skip: tuple = D.GHOSTING_SKIP
    sweep_scenes: tuple = D.SWEEP_SCENES
    agreement_samples: int = D.AGREEMENT_SAMPLES
    scenes: tuple = ()                    # scene specs; () = every built-in
    techniques: tuple = ()                # TechniqueConfigs
    out: str | None = None
    agreement: bool = True
    sweep: bool = False
    sharpen_sweep: tuple = ()             # strengths w of both thesis TAAs' sharpen (sharpen_sweep_configs)
    sharpen_sweep_scenes: tuple = D.SHARPEN_SWEEP_SCENES
    thesis_history: int = THESIS_HISTORY
    keep_frames: str = D.KEEP_FRAMES      # 'report': a run keeps, once judged, the frames the report reads; 'all'
    # 'whole': a test's runs keep every judged frame while its references refine (as the disk allows,
    # study.engine.disk.fit); 'pruned': pruned once judged, made again if the test is refined
    runs_while_refining: str = "whole"
    # the most the cache folder may hold: runs stay whole while they refine only within it too
    # (study.engine.disk.fit); it moves time, never a figure, so it is not in the repr either
    disk_budget_gb: float | None = field(default=None, repr=False)
    # False: a reference and the metrics records judged against it are removed once a finer bound
    # replaces them for this study (study.engine.supersede; the thesis profile). True keeps them for a
    # later study that starts there (an `ab` study's new column, a study of other scenes at the probe).
    # It changes no figure nor decision: not in the profile's repr, which keys the decisions' replay.
    keep_superseded: bool = field(default=True, repr=False)
    source: str = ""
    precision: Precision = Precision()    # how precise its references must be (study.engine.precision)
    video: Video = Video()                # the perceptual video metric (study.metrics.video)
    scene_groups: tuple = ()              # SceneGroups: scenes with their own tests and columns

    def group_of(self, spec: str, name: str) -> SceneGroup | None:
        """The scene group a scene (its spec, its name) is in, None for none."""
        return next((g for g in self.scene_groups if g.holds(spec, name)), None)

    def tests_of(self, spec: str, name: str, configs) -> tuple[list, object]:
        """A scene's columns from a run's `configs`, and whether it gets a protocol's test (a
        function of the protocol's name): its scene group's (SceneGroup), else every one."""
        group = self.group_of(spec, name)
        if group is None:
            return list(configs), lambda protocol: True
        return group.configs(configs, own=all(c in self.techniques for c in configs)), group.runs

    @property
    def static_views(self) -> dict[str, int]:
        """Labelled static protocols read from the one static run: label -> history length."""
        views = {f"thesis ({self.thesis_history} frames, cold)": self.thesis_history}
        if self.static.history != self.thesis_history:
            views[f"converged ({self.static.history} frames)"] = self.static.history
        return views


def view_history(label: str) -> int:
    """The history length a static view's label (Profile.static_views) names: its inverse, for a
    finished study's files, which keep the labels. ValueError for any other label."""
    import re
    m = re.fullmatch(r"thesis \((\d+) frames, cold\)|converged \((\d+) frames\)", label)
    if m is None:
        raise ValueError(f"{label!r} is not a static view's label (e.g. 'thesis (16 frames, cold)')")
    return int(m.group(1) or m.group(2))


def get_profile(name_or_file) -> Profile:
    """A built-in profile by name or a study file by path (study.config.studyfile)."""
    from study.config import studyfile
    if isinstance(name_or_file, Profile):
        return name_or_file
    if str(name_or_file).endswith(".toml"):
        return studyfile.load_study(name_or_file)
    return studyfile.profile(name_or_file)


