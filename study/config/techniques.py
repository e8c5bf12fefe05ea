"""Technique configurations: what a study column is, and where its technique class comes from.

A technique is named by a registry name (`taa_impl.TECHNIQUES`), by an entry point of the group
`taa_study.techniques` in an installed package, or by a file of the user's own,
`path/to/my_taa.py:ClassName`. All three give a `taa_impl.base.Technique` subclass driven exactly
like the built-in ones; its module's source (wherever it lives) is part of its cache key.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import json
import math
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from .lod import lod_bias as _lod_bias



@dataclass(frozen=True)
class TechniqueConfig:
    """A technique as a study names it: a column label, a registry name and parameter overrides;
    `lod_bias`: the raster's texture LOD bias for this column (None: `lod_bias`'s default rule)."""
    label: str
    name: str
    overrides: tuple = ()          # ((field, value), ...) so the config is hashable
    lod_bias: float | None = None

    def make(self):
        return resolve_technique(self.name)(**dict(self.overrides))

    def params(self):
        """The technique's parameters (its Params) as `make` would build it, without building it."""
        from taa_impl.base import build_params
        factory, o = resolve_technique(self.name), dict(self.overrides)
        params, feedback = o.pop("params", None), o.pop("feedback", None)
        if params is None:      # a registry preset's defaults, then the column's overrides
            o = {**getattr(factory, "defaults", {}), **o}
        return build_params(factory.Params, params, feedback, **o)

    def inputs(self):
        """What the technique needs (taa_impl.contract.Inputs) for these parameters, read without
        building it (a planner reads every column's for every test)."""
        return resolve_technique(self.name).inputs_for(self.params())

    def is_default(self, name: str) -> bool:
        """This is registry technique `name` with its default parameters (e.g. the thesis's TAA)."""
        if self.name != name:
            return False
        import taa_impl
        return self.params() == taa_impl.make(name).params

    def key_data(self) -> dict:
        """What identifies this technique's output: registry name, effective parameters, and the
        class whose code (and, transitively, the code it uses) produced it (see provenance)."""
        p, cls = self.params(), self.code()
        params = dataclasses.asdict(p) if dataclasses.is_dataclass(p) else repr(p)
        out = {"name": self.name, "params": params, "class": f"{cls.__module__}.{cls.__qualname__}"}
        if self.lod_bias is not None:    # the default rule is code the run's key already names (drive)
            out["lod_bias"] = float(self.lod_bias)
        return out

    def code(self) -> type:
        """The technique's class (a registry preset's), whose code keys its runs."""
        factory = resolve_technique(self.name)
        return getattr(factory, "cls", factory)

    @classmethod
    def parse(cls, text: str) -> "TechniqueConfig":
        """'name' or 'label=name:field=value,field=value' (values parsed as JSON when they can be);
        name may be 'path/to/file.py:ClassName'; 'lod_bias=value' sets the column's texture LOD bias."""
        head = text.split(":")[0]
        label, _, rest = text.partition("=") if "=" in head and ".py" not in head.split("=")[0] else ("", "", text)
        if ".py:" in rest:
            path, _, tail = rest.partition(".py:")
            cls_name, _, params = tail.partition(":")
            name = f"{Path(path + '.py').resolve()}:{cls_name}"
        else:
            name, _, params = rest.partition(":")
        overrides = []
        for item in filter(None, params.split(",")):
            k, eq, v = item.partition("=")
            if not eq and (Path(name).suffix or "/" in name or Path(name).exists()):
                # 'file.txt:Class': a file meant, not a registered name with overrides
                raise ValueError(f"technique {text!r}: a technique file must be a Python file "
                                 f"(path/to/file.py:ClassName), got {name!r}")
            if not eq:
                raise ValueError(f"technique {text!r}: override {item!r} is not field=value")
            try:
                val = json.loads(v)
            except json.JSONDecodeError:
                val = v
            overrides.append((k, tuple(val) if isinstance(val, list) else val))
        # lod_bias is the column's raster setting (study.config.lod), not a technique parameter
        bias = [v for k, v in overrides if k == "lod_bias"]
        if bias and (isinstance(bias[-1], bool) or not isinstance(bias[-1], (int, float))
                     or not math.isfinite(bias[-1])):
            raise ValueError(f"technique {text!r}: lod_bias must be a finite number, got {bias[-1]!r}")
        return cls(label or text, name, tuple((k, v) for k, v in overrides if k != "lod_bias"),
                   float(bias[-1]) if bias else None)


class TechniqueError(ValueError):
    pass


def upsamples(c: TechniqueConfig) -> bool:
    """The technique renders below the output's size at a render_scale (taa_impl.upscale)."""
    return bool(getattr(resolve_technique(c.name), "upsamples", False))


def render_scale(c: TechniqueConfig) -> float:
    return float(c.inputs().render_scale)


def at_scales(c: TechniqueConfig, scales) -> list[TechniqueConfig]:
    """One column per render scale of an upscaler, labelled '<label> ×<scale>'; a config whose
    overrides set render_scale, or that does not upsample, stays as it is."""
    if not scales or not upsamples(c) or any(k == "render_scale" for k, _ in c.overrides):
        return [c]
    return [TechniqueConfig(f"{c.label} ×{float(s):g}", c.name, (*c.overrides, ("render_scale", float(s))),
                            c.lod_bias) for s in scales]


def lod_bias(c: TechniqueConfig) -> float:
    """The texture LOD bias of a column's raster frames (study.config.lod: its own, else FSR 2's
    rule log2(render / display) - 1 for a temporal upscaler, log2(render / display) for a spatial
    one, 0 for the rest)."""
    return _lod_bias(c.lod_bias, c.inputs())


def family(c: TechniqueConfig) -> str:
    """An upscaler column's label without its ' ×<scale>' (the technique across scales)."""
    head, sep, tail = c.label.rpartition(" ×")
    return head if sep and tail == f"{render_scale(c):g}" else c.label


ENTRY_POINT_GROUP = "taa_study.techniques"


@lru_cache(maxsize=None)
def _file_module(path: str, mtime_ns: int):
    # A stable module name per file, registered in sys.modules so that provenance can find its source.
    name = "taa_user_" + hashlib.sha256(path.encode()).hexdigest()[:12]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise TechniqueError(f"technique file {path}: not a Python file")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
    except Exception as exc:
        del sys.modules[name]
        raise TechniqueError(f"technique file {path}: {type(exc).__name__}: {exc}") from None
    return mod


def resolve_technique(name: str):
    """The factory of a technique name: registry, entry point, or 'file.py:Class'."""
    import taa_impl
    from taa_impl.base import Technique
    if name in taa_impl.TECHNIQUES:
        return taa_impl.TECHNIQUES[name]
    if ".py:" in name:
        path, _, cls_name = name.rpartition(":")
        p = Path(path)
        if not p.is_file():
            raise TechniqueError(f"technique {name!r}: no file {path}")
        mod = _file_module(str(p.resolve()), p.stat().st_mtime_ns)
        obj = getattr(mod, cls_name, None)
        where = f"technique file {path}"
    else:
        from importlib.metadata import entry_points
        eps = [ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name == name]
        if not eps:
            raise TechniqueError(f"unknown technique {name!r}: not in the registry ({', '.join(sorted(taa_impl.TECHNIQUES))}), "
                                 f"not an entry point of {ENTRY_POINT_GROUP!r}, not 'file.py:Class'")
        try:
            obj = eps[0].load()
        except Exception as exc:
            raise TechniqueError(f"technique entry point {name!r}: {type(exc).__name__}: {exc}") from None
        cls_name, where = eps[0].value, f"entry point {name!r}"
    if obj is None:
        raise TechniqueError(f"{where} has no class {cls_name!r}")
    if not (isinstance(obj, type) and issubclass(obj, Technique)):
        raise TechniqueError(f"{where}: {cls_name} is not a taa_impl.base.Technique subclass")
    return obj


def available(configs) -> tuple[list, list]:
    """(configs whose technique resolves, configs that do not)."""
    ok, missing = [], []
    for c in configs:
        try:
            resolve_technique(c.name)
            ok.append(c)
        except TechniqueError:
            missing.append(c)
    return ok, missing
