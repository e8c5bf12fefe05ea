"""Scene descriptions: built-in scenes and user scene files, resolved into meshes and poses."""
from __future__ import annotations

import os

from .description import Scene
from .meshes import MeshData, SceneError, SceneWarning
from .resolved import PROFILES, ResolvedScene

__all__ = ["Scene", "ResolvedScene", "MeshData", "SceneError", "SceneWarning", "PROFILES", "get_scene", "builtin_names"]


def builtin_names() -> list[str]:
    from .builtin import BUILTIN
    return list(BUILTIN)


def get_scene(name_or_path: str) -> ResolvedScene:
    """A built-in scene by name, or a scene file (.toml / .json) by path."""
    from .builtin import BUILTIN
    if name_or_path in BUILTIN:
        return ResolvedScene(BUILTIN[name_or_path]())
    if os.path.splitext(name_or_path)[1] in (".toml", ".json") or os.path.isdir(name_or_path):
        from .loader import load_scene_file
        return load_scene_file(name_or_path)
    raise SceneError(f"unknown scene {name_or_path!r}: not a built-in ({', '.join(BUILTIN)}) "
                     "and not a .toml/.json file")
