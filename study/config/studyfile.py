"""Study files: a TOML file describes a whole study; the built-in quick and full profiles are
such files (study/config/profiles/*.toml).

    name = "my_study"
    scenes = ["pipe", "scenes/my_model.toml"]       # built-in names or scene files; [] = every built-in
    resolution = "quick"                             # "quick" | "full" (each scene's own) | [w, h]
    out = "out/my_study"                             # default: out/<name>
    agreement = true                                 # the reference agreement figure under each table
    sweep = false                                    # sparse supersampling's mu sweep
    render_scale = [0.5, 0.67, 1.0]                  # every upscaler's render scales; [] = its own default
    min_lod_bias = -4.0                              # the most negative texture LOD bias a column may use

    [[techniques]]                                   # none or [] = the default set (the quick profile's)
    label = "Uncharted"
    technique = "taa_baseline"                       # registry name, entry point or "file.py:Class"
    params = { sharpen = "normalised" }
    [[techniques]]
    spec = "Mine=my_taa.py:Box3x3TAA:widen=0.25"     # or the command line's form
    [[techniques]]
    spec = "FSR 2=fsr2"                              # an upscaler (taa_impl.upscale): one column per
    render_scale = [0.5, 1.0]                        #   scale, 'FSR 2 ×0.5' ...; default: the study's
    lod_bias = -1.5                                  # filtered textures' LOD bias for this column; default:
                                                     #   log2(render / display) - 1 for upscalers, else 0;
                                                     #   at least the study's min_lod_bias (default -4)

    [protocols.static]
    history = 256                                    # frames of history of the run
    checkpoints = [1, 2, 4, 8, 16, 32, 64, 128, 256] # history lengths judged
    thesis_history = 16                              # the labelled thesis protocol
    [[protocols.ghosting]]
    name = "ghosting"
    frames = 24
    warmup = 0                                       # frames at the first instant, not judged
    [reference]
    se_bound_lsb = 0.5                               # settings of references.ReferenceCache.get
    target_noise_db = 60.0                           #   (under rule = "per_pixel")
    reuse = true                                     # ghosting frames keep unchanged pixels of the one before
                                                     #   (or ["sphere_ghosting", ...]: those scenes only)
    [precision]                                      # study.engine.precision
    rule = "figures"                                 # or "per_pixel": every reference at [reference]
    psnr_db = 0.01                                   # each figure's reference uncertainty at most this
    ssim = 1e-4
    flip = 1e-4
    relative = 0.0023                                # MSE, RMSD, temporal RMS (0.01 dB of PSNR)
    relmse = 0.01                                    # relMSE HDR, a fraction of it
    start_bound_lsb = 8.0                            # each test's references probed at this per-pixel bound,
    finest_bound_lsb = 0.125                         #   then at what the figures ask for, down to this
    confirm = false                                  # true: a test settled at the probe once more, finer
    exempt = []                                      # column labels whose figures set no precision, or
                                                     #   {column, figures, tests, scenes}: only those ([]: all)
    [video]                                          # the perceptual video metric (study.metrics.video)
    metric = "cvvdp"                                 # ColorVideoVDP, in JOD; or "none"
    display = "standard_fhd"                         # a cvvdp display model
    fps = 60.0                                       # the frame rate a ghosting test is played at
    tests = ["ghosting"]                             # and/or "static" (the static views' image pairs)
    protocols = []                                   # protocol names of those tests; [] = every one
    scenes = []                                      # [] = every scene of those tests
    techniques = []                                  # column labels or registry names; [] = every column
    device = "auto"                                  # torch's device for it: "cuda" where torch sees one; "cpu"; "cuda"
    [[scene_groups]]                                 # scenes tested on their own terms
    name = "hard cases"
    scenes = ["specular_shimmer", "texture_crawl"]   #   each one of the study's scenes, in one group at most
    tests = ["ghosting"]                             #   protocol names ("static", the ghosting ones); [] = all
    columns = ["No AA", "Uncharted"]                 #   labels of [[techniques]]; [] = all
    [[scene_groups.techniques]]                      #   columns these scenes alone get, after those
    spec = "Variance clip=taa_variance"
    [[scene_groups.exempt]]                          #   figures that set no bound on these scenes
    column = "No AA"
    figures = ["mse", "psnr"]                        #   [] = all; tests = [...] too

Relative paths (scenes, technique files, out) are relative to the study file. A bad file exits 2
with the file, the field and the value. A run given other columns than the study's own
(--techniques, `ab`) tests a scene group's scenes with those, under the group's tests.
"""
from __future__ import annotations

import inspect
import tomllib
from pathlib import Path
from typing import Any, Literal, Union

from pydantic import Field, ValidationError, field_validator

from . import defaults as D
from .lod import MIN_LOD_BIAS
from .precision import Exemption, Precision
from .profile import Profile
from .protocols import Protocol
from .study_entries import (ExemptEntry, SceneGroupEntry, TechniqueEntry, _Model, check_exempt, columns, resolved,
                            scene_groups, scene_spec)
from .video import Video

PROFILE_DIR = Path(__file__).resolve().parent / "profiles"


class StudyFileError(ValueError):
    pass


class StaticEntry(_Model):
    history: int = Field(D.STATIC_HISTORY, ge=1)
    checkpoints: list[int] = Field(default_factory=lambda: list(D.STATIC_CHECKPOINTS))
    thesis_history: int = Field(D.THESIS_HISTORY, ge=1)


class GhostingEntry(_Model):
    name: str
    frames: int = Field(D.GHOSTING_FRAMES, ge=1)
    warmup: int = Field(D.GHOSTING_WARMUP, ge=0)


class PrecisionEntry(_Model):
    rule: Literal["figures", "per_pixel"] = D.PRECISION["rule"]
    psnr_db: float = Field(D.PRECISION["psnr_db"], gt=0)
    ssim: float = Field(D.PRECISION["ssim"], gt=0)
    flip: float = Field(D.PRECISION["flip"], gt=0)
    relative: float = Field(D.PRECISION["relative"], gt=0)
    relmse: float = Field(D.PRECISION["relmse"], gt=0)
    start_bound_lsb: float = Field(D.PRECISION["start_bound_lsb"], gt=0, le=64)
    finest_bound_lsb: float = Field(D.PRECISION["finest_bound_lsb"], gt=0)
    confirm: bool = D.PRECISION["confirm"]
    exempt: list[Union[str, ExemptEntry]] = Field(default_factory=list)

    @field_validator("finest_bound_lsb")
    @classmethod
    def _finest(cls, v, info):
        start = info.data.get("start_bound_lsb")
        if start is not None and v > start:
            raise ValueError(f"must be at most start_bound_lsb ({start})")
        return v


class VideoEntry(_Model):
    metric: Literal["cvvdp", "none"] = D.VIDEO["metric"]
    display: str = D.VIDEO["display"]
    fps: float = Field(D.VIDEO["fps"], gt=0, le=1000)
    tests: list[Literal["ghosting", "static"]] = Field(default_factory=lambda: list(D.VIDEO["tests"]))
    protocols: list[str] = Field(default_factory=list)
    scenes: list[str] = Field(default_factory=list)
    techniques: list[str] = Field(default_factory=list)
    device: Literal["auto", "cpu", "cuda"] = D.VIDEO["device"]

    @field_validator("display")
    @classmethod
    def _display(cls, v):
        from .video import display_models
        if v not in display_models():
            raise ValueError(f"unknown cvvdp display model; known: {', '.join(sorted(display_models()))}")
        return v


class ProtocolsEntry(_Model):
    static: StaticEntry = Field(default_factory=StaticEntry)
    ghosting: list[GhostingEntry] = Field(default_factory=lambda: [GhostingEntry(name="ghosting")])


class StudyModel(_Model):
    name: str = Field(min_length=1)
    scenes: list[str] = Field(default_factory=list)
    resolution: Union[Literal["quick", "full"], tuple[int, int]] = "quick"
    out: str | None = None
    agreement: bool = True
    agreement_samples: int = Field(D.AGREEMENT_SAMPLES, ge=1)
    sweep: bool = False
    sweep_scenes: list[str] = Field(default_factory=lambda: list(D.SWEEP_SCENES))
    ghosting_skip: list[str] = Field(default_factory=lambda: list(D.GHOSTING_SKIP))
    techniques: list[TechniqueEntry] = Field(default_factory=list)
    protocols: ProtocolsEntry = Field(default_factory=ProtocolsEntry)
    reference: dict[str, Any] = Field(default_factory=lambda: dict(D.REFERENCE))
    keep_frames: Literal["report", "all"] = D.KEEP_FRAMES
    runs_while_refining: Literal["whole", "pruned"] = "whole"
    disk_budget_gb: Union[float, None] = Field(None, gt=0)
    keep_superseded: bool = True
    precision: PrecisionEntry = Field(default_factory=PrecisionEntry)
    video: VideoEntry = Field(default_factory=VideoEntry)
    render_scale: list[float] = Field(default_factory=list)
    # the most negative texture LOD bias a column may use (explicit or by the upscalers' rule):
    # below it a minified texture aliases as much as an unfiltered one
    min_lod_bias: float = Field(MIN_LOD_BIAS, le=0)
    sharpen_sweep: list[float] = Field(default_factory=list)
    sharpen_sweep_scenes: list[str] = Field(default_factory=lambda: list(D.SHARPEN_SWEEP_SCENES))
    scene_groups: list[SceneGroupEntry] = Field(default_factory=list)

    @field_validator("sharpen_sweep")
    @classmethod
    def _strengths(cls, v):
        from taa_impl.base import check_sharpen
        if len(set(v)) != len(v):
            raise ValueError(f"sharpen strengths must be distinct, got {v}")
        for w in v:
            check_sharpen(float(w))
        return sorted(float(w) for w in v)

    @field_validator("render_scale")
    @classmethod
    def _scales(cls, v):
        from taa_impl.upscale import check_scale
        if len(set(v)) != len(v):
            raise ValueError(f"render scales must be distinct, got {v}")
        return [check_scale(s) for s in v]

    @field_validator("resolution")
    @classmethod
    def _size(cls, v):
        from scenes.description import MAX_SIDE     # the largest side the raster renders (raster.limits)
        if isinstance(v, tuple) and not all(8 <= x <= MAX_SIDE for x in v):
            raise ValueError(f"width and height must be in 8..{MAX_SIDE}, got {list(v)}")
        return v


def _where(loc) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def load_study(path: str | Path) -> Profile:
    """A study file as a Profile (what `study.engine.runner.Study` runs). Raises StudyFileError."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise StudyFileError(f"{path}: cannot read the study file ({exc.strerror})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise StudyFileError(f"{path}: not valid TOML ({exc})") from None
    try:
        m = StudyModel.model_validate(data)
    except ValidationError as exc:
        lines = [f"{path}: field {_where(e['loc'])}: {e['msg'].removeprefix('Value error, ')} "
                 f"(value: {e.get('input')!r})" for e in exc.errors()]
        raise StudyFileError("\n".join(lines)) from None
    base = path.resolve().parent

    def fail(field: str, value, msg: str):
        raise StudyFileError(f"{path}: field {field}: {msg} (value: {value!r})")

    configs = columns(m.techniques, "techniques", m, base, fail)
    if not configs:     # no techniques (or []): the default set, the built-in profile's
        default = PROFILE_DIR / f"{D.DEFAULT_TECHNIQUES_PROFILE}.toml"
        if path.resolve() == default.resolve():
            fail("techniques", [], "the built-in default profile must list its techniques")
        configs = list(profile(D.DEFAULT_TECHNIQUES_PROFILE).techniques)
    labels = [c.label for c in configs]
    if len(set(labels)) != len(labels):
        fail("techniques", labels, "labels must be unique")
    for t in m.video.techniques:
        if not any(t in (c.label, c.name) for c in configs):
            fail("video.techniques", t, "names no column of the study (a label or a registry name)")
    st = m.protocols.static
    try:
        static = Protocol("static", "static", history=st.history, checkpoints=tuple(sorted(set(st.checkpoints))))
    except ValueError as exc:
        fail("protocols.static", st.model_dump(), str(exc))
    if st.thesis_history not in static.checkpoints:
        fail("protocols.static.thesis_history", st.thesis_history, "must be one of the checkpoints")
    names = [g.name for g in m.protocols.ghosting]
    if len(set(names)) != len(names) or "static" in names:
        fail("protocols.ghosting", names, "names must be unique and not 'static'")
    ghosting = tuple(Protocol(g.name, "ghosting", frames=g.frames, warmup=g.warmup) for g in m.protocols.ghosting)
    from references import ReferenceCache
    allowed = set(inspect.signature(ReferenceCache.get).parameters) - {"self", "scene", "t", "width", "height",
                                                                        "progress"}
    for k, v in m.reference.items():
        if k not in allowed:
            fail(f"reference.{k}", v, f"unknown reference setting; known: {', '.join(sorted(allowed))}")
    scenes = []
    for i, s in enumerate(m.scenes):
        scenes.append(scene_spec(s, base))
    reuse = m.reference.get("reuse", False)
    if not isinstance(reuse, bool):     # the names of the scenes it is on for
        if not (isinstance(reuse, list) and all(isinstance(x, str) for x in reuse)):
            fail("reference.reuse", reuse, "must be true, false or a list of scene names")
        from scenes import get_scene
        known = [get_scene(sc).name for sc in scenes] if scenes else None
        for j, x in enumerate(reuse):
            if known is not None and x not in known:
                fail(f"reference.reuse[{j}]", x, f"names no scene of the study's ({', '.join(known)})")
        m.reference["reuse"] = tuple(reuse)
    for j, x in enumerate(m.video.protocols):
        if x not in ("static", *names):
            fail(f"video.protocols[{j}]", x, f"names no test of the study; known: {', '.join(('static', *names))}")
    groups, exemptions = scene_groups(m, base, scenes, configs, ("static", *names), fail)
    labels += [c.label for g in groups for c in g.techniques]
    for i, e in enumerate(m.precision.exempt):
        if isinstance(e, str):
            continue
        check_exempt(f"precision.exempt[{i}]", e, labels, ("static", *names), fail)
        for j, sc in enumerate(e.scenes):
            if scene_spec(sc, base) not in scenes and scenes:
                fail(f"precision.exempt[{i}].scenes[{j}]", sc, "names no scene of the study's scenes")
        exemptions.append(Exemption(e.column, e.figures, e.tests, [resolved(scene_spec(sc, base)) for sc in e.scenes]))
    prec = m.precision.model_dump()
    prec["exempt"] = [e for e in m.precision.exempt if isinstance(e, str)]
    out = m.out
    if out is not None and not Path(out).is_absolute():
        out = str(base / out)
    return Profile(name=m.name, resolution=m.resolution, static=static, ghosting=ghosting,
                   ref_settings=tuple(sorted(m.reference.items())), ghosting_techniques_skip=tuple(m.ghosting_skip),
                   sweep_scenes=tuple(m.sweep_scenes), agreement_samples=m.agreement_samples,
                   scenes=tuple(scenes), techniques=tuple(configs), out=out, agreement=m.agreement,
                   sweep=m.sweep, sharpen_sweep=tuple(m.sharpen_sweep), sharpen_sweep_scenes=tuple(m.sharpen_sweep_scenes),
                   thesis_history=st.thesis_history, keep_frames=m.keep_frames, runs_while_refining=m.runs_while_refining,
                   keep_superseded=m.keep_superseded, disk_budget_gb=m.disk_budget_gb,
                   source=str(path),
                   precision=Precision(**prec, exemptions=tuple(exemptions)), video=Video(**m.video.model_dump()),
                   scene_groups=tuple(groups))


def profile(name: str) -> Profile:
    """A built-in profile (study/config/profiles/<name>.toml)."""
    return load_study(PROFILE_DIR / f"{name}.toml")


def builtin_profiles() -> list[str]:
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))
