"""Loading scene files (TOML or JSON) with errors that name the file, the field and the value."""
from __future__ import annotations

import json
import os
import tomllib

from pydantic import ValidationError

from .description import Scene
from .meshes import SceneError
from .resolved import ResolvedScene


def _format(path: str, err: ValidationError) -> str:
    lines = [f"{path}: invalid scene description"]
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(top level)"
        val = e.get("input")
        shown = repr(val) if not isinstance(val, dict) else "{...}"
        lines.append(f"  field {loc}: {e['msg']} (value: {shown[:80]})")
    return "\n".join(lines)


def parse(data: dict, where: str) -> Scene:
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise SceneError(_format(where, err)) from None


def load_scene_file(path: str) -> ResolvedScene:
    if not os.path.isfile(path):
        raise SceneError(f"scene file not found: {path}")
    try:
        with open(path, "rb") as f:
            if path.endswith(".toml"):
                data = tomllib.load(f)
            elif path.endswith(".json"):
                data = json.load(f)
            else:
                raise SceneError(f"{path}: scene files must end in .toml or .json")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot parse: {exc}") from None
    desc = parse(data, path)
    try:
        return ResolvedScene(desc, base_dir=os.path.dirname(os.path.abspath(path)))
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None
