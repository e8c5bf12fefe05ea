"""A study file's columns and scene groups: the [[techniques]] entries (a study's and a scene
group's own), the [[scene_groups]] and [precision]'s exemption tables, read and checked
(study.config.studyfile reads the rest of the file)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator

from .precision import EXEMPTABLE, Exemption
from .profile import SceneGroup
from .techniques import TechniqueConfig, at_scales, lod_bias, upsamples


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class TechniqueEntry(_Model):
    label: str | None = None
    technique: str | None = None
    params: dict[str, Any] = Field(default_factory=dict)
    spec: str | None = None
    render_scale: Union[float, list[float], None] = None     # an upscaler's scales (else the study's)
    lod_bias: float | None = None          # texture LOD bias of the column (techniques.lod_bias)

    def config(self, base: Path) -> TechniqueConfig:
        if (self.spec is None) == (self.technique is None):
            raise ValueError("give either spec = 'Label=name:field=value' or technique = 'name' (with label, params)")
        if self.spec is not None:
            if self.label or self.params:
                raise ValueError("spec already holds the label and parameters")
            text = self.spec
        else:
            text = self.technique
        if ".py:" in text:
            head, _, tail = text.rpartition(".py:")
            lab, eq, path = head.rpartition("=") if "=" in head else ("", "", head)
            if not Path(path + ".py").is_absolute():
                path = str(base / (path + ".py"))[:-3]
            text = f"{lab}{eq}{path}.py:{tail}"
        c = TechniqueConfig.parse(text)
        if self.technique is not None:
            c = TechniqueConfig(self.label or c.label, c.name,
                                tuple((k, tuple(v) if isinstance(v, list) else v) for k, v in self.params.items()))
        if self.lod_bias is not None:
            c = TechniqueConfig(c.label, c.name, c.overrides, float(self.lod_bias))
        return c


class GroupExemptEntry(_Model):
    column: str | None = Field(None, min_length=1)     # None: every column
    figures: list[str] = Field(default_factory=list)
    tests: list[str] = Field(default_factory=list)

    @field_validator("figures")
    @classmethod
    def _figures(cls, v):
        unknown = [f for f in v if f not in EXEMPTABLE]
        if unknown:
            raise ValueError(f"unknown figure {unknown[0]!r}; known: {', '.join(EXEMPTABLE)}")
        return v


class ExemptEntry(GroupExemptEntry):
    scenes: list[str] = Field(default_factory=list)


class SceneGroupEntry(_Model):
    name: str = Field(min_length=1)
    scenes: list[str] = Field(min_length=1)
    tests: list[str] = Field(default_factory=list)
    columns: list[str] = Field(default_factory=list)
    techniques: list[TechniqueEntry] = Field(default_factory=list)
    exempt: list[GroupExemptEntry] = Field(default_factory=list)


def columns(entries, field: str, m, base: Path, fail) -> list[TechniqueConfig]:
    """The columns a list of [[techniques]] entries makes (an upscaler's one per render scale)."""
    configs = []
    for i, t in enumerate(entries):
        try:
            c = t.config(base)
            c.make()
            scales = m.render_scale
            if t.render_scale is not None:
                if not upsamples(c):
                    raise ValueError("render_scale is for a technique that upsamples (taa_impl.upscale)")
                scales = [t.render_scale] if isinstance(t.render_scale, (int, float)) else t.render_scale
                if not scales or len(set(scales)) != len(scales):
                    raise ValueError(f"render_scale needs distinct scales, got {t.render_scale!r}")
            scaled = at_scales(c, scales)
            for sc in scaled:
                sc.make()
        except (ValueError, TypeError, KeyError) as exc:
            fail(f"{field}[{i}]", t.spec or t.technique, str(exc))
        for sc in scaled:
            bias = lod_bias(sc)
            if bias < m.min_lod_bias:
                how = "" if sc.lod_bias is not None else f" (the upscalers' rule, study.config.lod, for {sc.label!r})"
                fail(f"{field}[{i}].lod_bias", bias, f"more negative than min_lod_bias = {m.min_lod_bias:g}{how}")
        configs.extend(scaled)
    return configs


def scene_spec(s: str, base: Path) -> str:
    """A scene as the study lists it: a built-in's name, a scene file's path from the study file's folder."""
    return str(base / s) if s.endswith((".toml", ".json")) and not Path(s).is_absolute() else s


def resolved(spec: str) -> str:
    """A scene spec as a scene group and an exemption hold it: a scene file's resolved path."""
    return str(Path(spec).resolve()) if spec.endswith((".toml", ".json")) else spec


def check_exempt(field: str, e, labels: list, tests: tuple, fail) -> None:
    """Fail (`fail(field, value, message)`) where an exemption entry names a column not among
    `labels` or a test not among `tests`."""
    if e.column is not None and e.column not in labels:
        fail(f"{field}.column", e.column, "names no column of the study (its labels)")
    for j, t in enumerate(e.tests):
        if t not in tests:
            fail(f"{field}.tests[{j}]", t, f"names no test of the study; known: {', '.join(tests)}")


def scene_groups(m, base: Path, scenes: list, configs: list, tests: tuple, fail) -> tuple[list, list]:
    """The study file's [[scene_groups]] as SceneGroups, and the Exemptions they make."""
    from scenes import builtin_names
    known = scenes or builtin_names()
    study_labels = [c.label for c in configs]
    groups, exemptions, taken = [], [], {}
    for i, g in enumerate(m.scene_groups):
        where = f"scene_groups[{i}]"
        if any(o.name == g.name for o in groups):
            fail(f"{where}.name", g.name, "names another group too")
        specs = []
        for j, sc in enumerate(g.scenes):
            spec = scene_spec(sc, base)
            if spec not in known:
                fail(f"{where}.scenes[{j}]", sc, "names no scene of the study's scenes"
                     + ("" if scenes else " (every built-in)"))
            if spec in taken:
                fail(f"{where}.scenes[{j}]", sc, f"is in group {taken[spec]!r} too")
            taken[spec] = g.name
            specs.append(resolved(spec))
        for j, t in enumerate(g.tests):
            if t not in tests:
                fail(f"{where}.tests[{j}]", t, f"names no test of the study; known: {', '.join(tests)}")
        own = columns(g.techniques, f"{where}.techniques", m, base, fail)
        for c in own:
            if c.label in study_labels or [o.label for o in own].count(c.label) > 1:
                fail(f"{where}.techniques", c.label, "labels must be unique among the study's columns and the group's")
        for j, label in enumerate(g.columns):
            if label not in study_labels:
                fail(f"{where}.columns[{j}]", label, "names no column of the study's [[techniques]] (a label)")
        group = SceneGroup(g.name, tuple(specs), tuple(g.tests), tuple(g.columns), tuple(own))
        cols = [c.label for c in group.configs(configs, own=True)]
        for j, e in enumerate(g.exempt):
            check_exempt(f"{where}.exempt[{j}]", e, cols, g.tests or tests, fail)
            exemptions.append(Exemption(e.column, e.figures, e.tests, specs))
        groups.append(group)
    return groups, exemptions
