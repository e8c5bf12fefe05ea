"""Content keys: one function builds every cache key from what determines the artefact.

A key is `task_key(kind, data, inputs, code)`:
  data    plain values (parameters, resolutions, schedules), tokenised by Dask's `tokenize`
          (deterministic for dicts, tuples, NumPy arrays and dataclasses);
  inputs  the keys of the artefacts the task reads (a reference's key, a run's key), so a changed
          input changes every key downstream of it;
  code    modules, classes or functions whose source produced it. `code_token` hashes the source
          files of those modules and, transitively, of every module they use that is not part of
          Python or an installed package (those are pinned in pyproject.toml), so the project's own
          code and a user's technique file both take part, wherever the file lives. A module that
          reads other source files (shaders) lists them as `__code_files__` (globs relative to it).
"""
from __future__ import annotations

import ast
import contextlib
import hashlib
import sys
import sysconfig
import types
from functools import lru_cache
from pathlib import Path

from dask.base import normalize_token, tokenize

_INSTALLED = tuple(str(Path(p).resolve()) for p in {sysconfig.get_paths()["stdlib"],
                                                    sysconfig.get_paths()["purelib"],
                                                    sysconfig.get_paths()["platlib"]})


def _own_module(mod) -> bool:
    """A module of the project or of the user: has a source file outside Python and site-packages."""
    f = getattr(mod, "__file__", None)
    return bool(f) and f.endswith(".py") and _own_file(f)


@lru_cache(maxsize=None)
def _own_file(f: str) -> bool:          # resolving each module's path was a fifth of a plan's keying
    return not str(Path(f).resolve()).startswith(_INSTALLED)


def _module_of(obj):
    if isinstance(obj, types.ModuleType):
        return obj
    if isinstance(obj, str):
        __import__(obj)
        return sys.modules[obj]
    return sys.modules.get(getattr(obj, "__module__", None) or "")


@lru_cache(maxsize=None)
def _static_imports(path: str, mtime_ns: int, package: str) -> tuple[frozenset[str], frozenset[str]]:
    """What a source file's top-level import statements name, as absolute module names: the
    submodules an `import a.b.c` loads without binding them (a.b, a.b.c), and every name any import
    statement gives (`from .x import y`: package.x and package.x.y, whether y is a module or not)."""
    tree = ast.parse(Path(path).read_bytes(), filename=path)
    dotted: set[str] = set()
    named: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                names = [".".join(parts[:i]) for i in range(1, len(parts) + 1)]
                named.update(names)
                dotted.update(names[1:] if alias.asname is None else ())
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            named.add(mod)
            named.update(f"{mod}.{alias.name}" for alias in node.names)
    return frozenset(dotted), frozenset(named)


@lru_cache(maxsize=None)
def _closure(root: str) -> tuple[str, ...]:
    """Names of the own modules `root` uses, itself included: what its globals refer to, and the
    submodules its `import a.b` statements load (such a statement binds only `a`).

    Not a package's submodules merely because they are loaded (importing `a.b` anywhere binds `b`
    on package `a`): which are loaded depends on what else the process imported first, and a key
    must not (a command that had loaded one more submodule computed other keys than the study
    that cached the tasks). A package's submodule counts when its own source imports it."""
    seen: set[str] = set()
    todo = [root]
    while todo:
        name = todo.pop()
        mod = sys.modules.get(name)
        if name in seen or mod is None or not _own_module(mod):
            continue
        seen.add(name)
        path = _source_of(mod.__file__)
        package = name if hasattr(mod, "__path__") else name.rpartition(".")[0]
        dotted, named = _static_imports(str(path), path.stat().st_mtime_ns, package)
        todo += dotted
        for v in list(vars(mod).values()):
            m = v if isinstance(v, types.ModuleType) else sys.modules.get(getattr(v, "__module__", None) or "")
            if m is None or m.__name__ in seen:
                continue
            if m is v and m.__name__.startswith(name + ".") and m.__name__ not in named:
                continue        # bound on this package by whoever imported it
            todo.append(m.__name__)
    return tuple(sorted(seen))


@lru_cache(maxsize=None)
def _file_digest(path: str, mtime_ns: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


_SNAPSHOT: dict | None = None


@contextlib.contextmanager
def code_snapshot():
    """Within the block each set of modules is hashed once: a plan's keys see one state of the code
    (a quick study's plan keyed 5359 tasks, each reading the state of some 50 files again)."""
    global _SNAPSHOT
    outer = _SNAPSHOT
    if outer is None:
        _SNAPSHOT = {}
    try:
        yield
    finally:
        if outer is None:
            _SNAPSHOT = None


def code_token(*objs) -> str:
    """Hash of the source of the given modules/classes/functions and the own modules they use."""
    names: set[str] = set()
    for obj in objs:
        mod = _module_of(obj)
        if mod is None:
            raise ValueError(f"cannot find the module of {obj!r} to key its code")
        if not _own_module(mod):
            continue
        names.update(_closure(mod.__name__))
    memo = frozenset(names)
    if _SNAPSHOT is not None and memo in _SNAPSHOT:
        return _SNAPSHOT[memo]
    h = hashlib.sha256()
    for path in code_files(names):
        h.update(path.name.encode())
        h.update(_file_digest(str(path), path.stat().st_mtime_ns).encode())
    token = h.hexdigest()[:16]
    if _SNAPSHOT is not None:
        _SNAPSHOT[memo] = token
    return token


@lru_cache(maxsize=None)
def _source_of(file: str) -> Path:
    return Path(file).resolve()


def code_files(names) -> list[Path]:
    """The source files of the named modules, with the files they declare in `__code_files__`."""
    out = []
    for name in sorted(names):
        mod = sys.modules[name]
        path = _source_of(mod.__file__)
        out.append(path)
        for pattern in getattr(mod, "__code_files__", ()):
            out += sorted(p.resolve() for p in path.parent.glob(pattern) if p.is_file())
    return out


def closure_files(*objs) -> list[Path]:
    """Every file `code_token(*objs)` hashes."""
    names: set[str] = set()
    for obj in objs:
        mod = _module_of(obj)
        if mod is not None and _own_module(mod):
            names.update(_closure(mod.__name__))
    return code_files(names)


class Normalized:
    """A value already normalised for `tokenize`: it tokenises exactly as the value it was made from
    (the same key), without walking it again. A plan keys each technique's run by the same schedule."""
    __slots__ = ("value",)

    def __init__(self, obj):
        self.value = normalize_token(obj)


normalize_token.register(Normalized)(lambda n: n.value)


def task_key(kind: str, data=None, inputs=(), code=()) -> str:
    """The key of an artefact of `kind` made from `data`, the artefacts `inputs` and `code`."""
    return f"{kind}-{tokenize(kind, data, sorted(inputs) if isinstance(inputs, set) else list(inputs), code_token(*code))[:20]}"


__all__ = ["task_key", "Normalized", "code_token", "code_snapshot", "closure_files", "tokenize"]
