"""Loading scene files (TOML or JSON) with errors that name the file, the field and the value."""
from __future__ import annotations

import json
import os
import tomllib

from pydantic import ValidationError

from .description import Scene
from .meshes import SceneError
from .resolved import ResolvedScene


def field_path(loc: tuple, data) -> str:
    """`lights[0].intensity[1]` from pydantic's loc. Steps that are not in the data (the tag of a
    discriminated union, such as 'directional') are dropped by walking the raw input alongside."""
    out, node = "", data
    for i, step in enumerate(loc):
        if isinstance(step, int) and isinstance(node, (list, tuple)):
            out += f"[{step}]"
            node = node[step] if -len(node) <= step < len(node) else None
        elif isinstance(node, dict) and step not in node and (
                step in node.values() or (i + 1 < len(loc) and loc[i + 1] in node)):
            continue
        else:
            out += f".{step}" if out else str(step)
            node = node.get(step) if isinstance(node, dict) else None
    return out or "(top level)"


def _format(path: str, err: ValidationError, data) -> str:
    lines = [f"{path}: invalid scene description"]
    for e in err.errors():
        loc = field_path(e["loc"], data)
        val = e.get("input")
        shown = repr(val) if not isinstance(val, dict) else "{...}"
        msg = e["msg"].removeprefix("Value error, ")
        lines.append(f"  field {loc}: {msg} (value: {shown[:80]})")
    return "\n".join(lines)


def parse(data: dict, where: str) -> Scene:
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise SceneError(_format(where, err, data)) from None


def load_scene_file(path: str) -> ResolvedScene:
    if os.path.isdir(path):
        raise SceneError(f"{path}: is a folder, not a scene file (give a .toml or .json file)")
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
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc.strerror})") from None
    desc = parse(data, path)
    return ResolvedScene(desc, base_dir=os.path.dirname(os.path.abspath(path)), source=path)
