"""`taa-study run`: the static and ghosting tests on a set of scenes, make-style.

Artefacts are keyed by the content of what produced them: a technique's run by the scene's content
hash, the protocol and its schedule, the resolution, the technique's parameters and the source of
taa_impl/, raster/, shading/ and scenes/; metrics additionally by the reference keys and the
metric code. A second run with nothing changed renders nothing and reads the cached metrics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from display import DisplayTransform
from references import ReferenceCache
from references.exr import write_exr
from scenes import ResolvedScene

from . import metrics as M
from .config import PROFILES, Profile, TechniqueConfig, source_hash, stable_hash
from .protocols import ghosting_schedule, run_schedule, static_schedule
from .store import RunStore

# Scene content (meshes, textures, description) is in the scene's own hash; the code listed here is
# what turns a scene into frames: camera, jitter, animation, raster, shading, and the driver.
RASTER_CODE = ("raster/*.py", "raster/shaders/*", "shading/*.py", "scenes/camera.py", "scenes/jitter.py",
               "scenes/resolved.py", "study/protocols.py")
METRIC_CODE = ("study/metrics.py", "display/*.py")


def is_animated(scene: ResolvedScene) -> bool:
    f = set(scene.desc.features())
    return scene.desc.frames > 1 and bool(f & {"moving_object", "moving_camera", "camera_cut"})


@dataclass
class TestResult:
    scene: str
    test: str                                  # static | ghosting
    frames: list[int]
    per_frame: dict[str, dict[int, dict]]      # label -> t -> metrics
    ms: dict[str, float]
    temporal: dict[str, float] = field(default_factory=dict)
    recomputed: list[str] = field(default_factory=list)
    artefacts: dict[str, dict] = field(default_factory=dict)   # label -> folder, metrics key, output space
    stats: dict[str, dict] = field(default_factory=dict)       # label -> t -> technique counters (sparse SS)
    reference_keys: dict[int, str] = field(default_factory=dict)
    width: int = 0
    height: int = 0


class Study:
    def __init__(self, profile: str = "quick", cache_root: Path | None = None, progress: bool = True,
                 log=print):
        self.profile: Profile = PROFILES[profile]
        self.cache = ReferenceCache(cache_root)
        self.store = RunStore(self.cache.root)
        self.progress, self.log = progress, log
        self.raster_code = source_hash(*RASTER_CODE)
        self.metric_code = source_hash(*METRIC_CODE)
        self.stats = {"runs_computed": 0, "runs_cached": 0, "metrics_computed": 0, "references_rendered": 0}

    def resolution(self, scene: ResolvedScene) -> tuple[int, int]:
        return scene.resolution("full" if self.profile.use_full_resolution else "quick")

    def reference(self, scene: ResolvedScene, t: int, w: int, h: int):
        ref, cached = self.cache.get(scene, t, w, h, target_noise_db=self.profile.target_noise_db)
        if not cached:
            self.stats["references_rendered"] += 1
        return ref

    # -- one test ----------------------------------------------------------------------------
    def run_test(self, scene: ResolvedScene, test: str, configs: list[TechniqueConfig]) -> TestResult:
        w, h = self.resolution(scene)
        if test == "static":
            schedule = static_schedule(0, self.profile.history_frames)
        else:
            configs = [c for c in configs if c.name not in self.profile.ghosting_techniques_skip]
            schedule = ghosting_schedule(scene, min(scene.desc.frames, self.profile.ghosting_frames))
        kept = [s.t for s in schedule if s.keep]
        refs = {}
        for t in tqdm(kept, desc=f"{scene.name}: references", unit="frame", disable=not self.progress,
                      leave=False):
            refs[t] = self.reference(scene, t, w, h)
        displays = {t: DisplayTransform.from_reference(r.image) for t, r in refs.items()}

        base = {"scene": scene.content_hash, "test": test, "schedule": [(s.t, s.k, s.keep, s.reset, s.prev_t) for s in schedule],
                "res": (w, h), "raster": self.raster_code}
        keys = {c.label: stable_hash({**base, "technique": c.key()}) for c in configs}
        folders = {c.label: self.store.folder(test, scene.name, keys[c.label]) for c in configs}
        runs, missing = {}, []
        for c in configs:
            got = self.store.load(folders[c.label], keys[c.label])
            if got is None:
                missing.append(c)
            else:
                runs[c.label] = got
                self.stats["runs_cached"] += 1
        if missing:
            fresh = run_schedule(scene, w, h, schedule, missing, displays,
                                 desc=f"{scene.name}: {test} ({', '.join(c.label for c in missing)})",
                                 progress=self.progress)
            for c in missing:
                r = fresh[c.label]
                meta = {"label": c.label, "technique": c.name, "overrides": list(c.overrides),
                        "output_space": r["output_space"], "ms": r["ms"], "nonfinite": r["nonfinite"],
                        "stats": {str(t): v for t, v in r["stats"].items()}}
                self.store.save(folders[c.label], keys[c.label], r["images"], meta)
                runs[c.label] = {"meta": {**meta, "frames": kept}, "images": r["images"]}
                self.stats["runs_computed"] += 1

        res = TestResult(scene.name, test, kept, {}, {}, recomputed=[c.label for c in missing],
                         reference_keys={t: refs[t].key for t in kept}, width=w, height=h)
        ref8 = {t: displays[t].to_8bit(refs[t].image) for t in kept}
        for c in configs:
            run = runs[c.label]
            mkey = stable_hash({"run": keys[c.label], "refs": [refs[t].key for t in kept], "code": self.metric_code})
            mpath = folders[c.label] / f"metrics_{mkey}.json"
            data = self.store.load_json(mpath, mkey)
            if data is None:
                data, maps = M.judge_run(run["images"], run["meta"]["output_space"], refs, displays, ref8, kept)
                if test == "static":
                    write_exr(folders[c.label] / f"maps_{mkey}.exr", maps)
                self.store.save_json(mpath, mkey, data)
                self.stats["metrics_computed"] += 1
            res.per_frame[c.label] = {int(t): v for t, v in data["per_frame"].items()}
            res.ms[c.label] = run["meta"]["ms"]
            if run["meta"].get("stats"):
                res.stats[c.label] = {int(t): v for t, v in run["meta"]["stats"].items()}
            res.temporal[c.label] = data.get("temporal", math.nan)
            res.artefacts[c.label] = {"folder": folders[c.label], "metrics_key": mkey, "run_key": keys[c.label],
                                      "output_space": run["meta"]["output_space"], "technique": c.name,
                                      "overrides": list(c.overrides)}
        return res

    # -- the floor under a comparison ------------------------------------------------------------
    def agreement(self, scene: ResolvedScene) -> dict:
        from study.agreement import check_agreement
        w, h = self.resolution(scene)
        samples = 256 if self.profile.use_full_resolution else 64
        ref = self.reference(scene, 0, w, h)
        key = stable_hash({"scene": scene.content_hash, "res": (w, h), "raster": self.raster_code,
                           "ref": ref.key, "samples": samples, "code": source_hash("study/agreement.py")})
        path = self.store.root / "agreement" / scene.name / f"{key}.json"
        data = self.store.load_json(path, key)
        if data is None:
            a = check_agreement(scene, w, h, samples=samples, cache=self.cache,
                                target_noise_db=self.profile.target_noise_db, progress=self.progress)
            data = a.as_dict()
            self.store.save_json(path, key, data)
        return data
