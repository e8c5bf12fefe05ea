"""The proof that the raster and the reference see the same scene.

- agreement: mean of N jittered raster frames (Halton(2,3), period N) against the Mitsuba
  reference, as PSNR of display images (display/__init__.py, before 8-bit quantisation; the
  reference's noise removed with its halves, study.metrics.uncertainty) and as
  relative MSE in linear HDR, mean((x - r)^2 / (r^2 + 0.01)).
- interior error: raster pixel centre (zero jitter) against one Mitsuba ray through the same
  point, max |difference| over pixels whose 3x3 raster object ids and light masks agree and whose
  centre sees the same object and triangle in both renderers (away from geometric and shadow edges).
- single sample: the visibility framebuffer has one sample per pixel, and the raster's pixel
  centres reproduce single rays (fraction of all pixels matching to 1e-4).
- reference bound: every reference pixel's display-domain standard error within the bound it
  was rendered to (0.5 LSB by default); the bound, the 99.9th percentile and max SE are reported.
- something to see: at least one pixel centre hits an object in both renderers. A frame of
  background only (a camera looking away, or a broken camera) agrees perfectly and proves nothing.

Filtered textures (docs/method.md, "Texture filtering"): the raster here samples every bilinear
or trilinear texture on its base level, bilinearly (Rasterizer(mipmaps=False)), the function the
reference integrates; a mip level is a prefilter the reference does not have, so comparing it would
measure the filter, not whether the two renderers agree. The study's columns use the mip chain.
"""
from __future__ import annotations

import math

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from display import DisplayTransform
from raster import Rasterizer
from references import ReferenceCache, trace_pixel_centres
from references import settings as S
from scenes import ResolvedScene
from scenes.jitter import halton_offsets
from study.engine.tasks import Context, _deterministic, _setup, display_of, load_scene
from study.metrics.uncertainty import jackknife

from study.config.defaults import AGREEMENT_TARGETS as TARGETS  # noqa: E402


@dataclass
class Agreement:
    scene: str
    frame: int
    width: int
    height: int
    agreement_psnr_db: float
    relative_mse: float
    interior_max_abs_err: float
    interior_pixels: int
    centre_match_fraction: float
    reference_noise_psnr_db: float
    reference_spp: int
    reference_seconds: float
    reference_cached: bool
    raster_samples: int
    raster_seconds: float
    single_sample: bool
    transport: str = "direct"
    reference_se_bound_lsb: float = S.SE_BOUND_LSB
    reference_se_p999_lsb: float = 0.0
    reference_se_max_lsb: float = 0.0
    reference_over_bound: int = 0
    reference_spp_max: int = 0
    reference_spp_needed: int = 0     # what the worst pixel over the bound would take (0: none over)
    visible_fraction: float = 1.0     # pixel centres that hit an object, in both renderers
    agreement_u_db: float = 0.0       # the reference's share of agreement_psnr_db's uncertainty
    # The PSNR at the upper end of the MSE's uncertainty: the floor is checked there. (agreement_psnr_db
    # - agreement_u_db is a first-order bound, meaningless where the MSE's uncertainty is near the MSE
    # itself: a near-exact 82 dB against an 8-LSB reference read "82 +- 660 dB", below 45.) None: not
    # recorded (an older record): the first-order bound.
    agreement_floor_db: float | None = None
    # 'per_pixel': a reference to the [reference] bound and noise target, which are then targets too;
    # 'figures': one at the precision a study's figures need (study.engine.precision), whose noise
    # the agreement removes with its halves and carries as agreement_u_db.
    reference_rule: str = "per_pixel"

    def meets_targets(self) -> dict[str, bool]:
        # A 'path' reference is a realism study: its gap to the direct-lit raster is reported only.
        reported_only = self.transport == "path"
        per_pixel = self.reference_rule == "per_pixel"
        # the floor must hold at the lower end of the figure's reference uncertainty
        return {"agreement_psnr_db": reported_only or
                self.floor_db >= TARGETS["agreement_psnr_db"],
                "interior_max_abs_err": reported_only or
                self.interior_max_abs_err <= TARGETS["interior_max_abs_err"],
                "reference_noise_psnr_db": not per_pixel or
                self.reference_noise_psnr_db >= TARGETS["reference_noise_psnr_db"],
                "reference_bound": not per_pixel or self.reference_over_bound == 0,
                "single_sample": self.single_sample,
                "objects_visible": self.visible_fraction > 0}

    @property
    def floor_db(self) -> float:
        """The agreement's PSNR at the lower end of its reference uncertainty."""
        return self.agreement_psnr_db - self.agreement_u_db if self.agreement_floor_db is None else self.agreement_floor_db

    def as_dict(self) -> dict:
        d = {k: (v.item() if hasattr(v, "item") else v) for k, v in asdict(self).items()}
        d["targets_met"] = {k: bool(v) for k, v in self.meets_targets().items()}
        return d


def _interior(ids: np.ndarray) -> np.ndarray:
    pad = np.pad(ids, 1, mode="edge")
    h, w = ids.shape
    same = np.ones_like(ids, bool)
    for dy in range(3):
        for dx in range(3):
            same &= pad[dy:dy + h, dx:dx + w] == ids
    return same


def check_agreement(scene: ResolvedScene, width: int, height: int, *, frame: int = 0, samples: int = 256,
                    cache: ReferenceCache | None = None, target_noise_db: float = S.TARGET_NOISE_DB,
                    se_bound_lsb: float = S.SE_BOUND_LSB, held_out: bool = False, progress: bool = True,
                    display: DisplayTransform | None = None) -> Agreement:
    """`display`: the transform both are judged under (a study's: study.engine.tasks.display_of);
    by default the reference's own."""
    import time
    cache = cache or ReferenceCache()
    raster = Rasterizer(scene, width, height, mipmaps=False)   # the module notes: the base level
    try:
        t0 = time.perf_counter()
        acc = np.zeros((height, width, 3), np.float64)
        for ox, oy in tqdm(halton_offsets(samples), desc=f"{scene.name}: raster", unit="frame",
                           disable=not progress, leave=False, mininterval=1.0):
            acc += raster.render(frame, (ox, oy), ("color",))["color"]
        mean = acc / samples
        raster_s = time.perf_counter() - t0
        centre = raster.render(frame, (0.0, 0.0), ("color", "object_id", "prim_id", "light_mask"))
        spp_gl = raster.samples_per_pixel
    finally:
        raster.close()

    bar = tqdm(desc=f"{scene.name}: reference", unit="spp", disable=not progress, leave=False, mininterval=1.0)
    ref, cached = cache.get(scene, frame, width, height, target_noise_db=target_noise_db,
                            se_bound_lsb=se_bound_lsb, held_out=held_out, progress=lambda spp, db: (bar.update(spp - bar.n), bar.set_postfix(noise_db=f"{db:.1f}")))
    bar.close()

    disp = display or DisplayTransform.from_reference(ref.image)
    x = disp.encode(mean).astype(np.float64)
    # the reference's noise removed with its two halves (study.metrics.uncertainty), as for every figure
    figs = [{"mse": float(np.mean((x - disp.encode(r)) ** 2)) * 255.0 ** 2} for r in (ref.image, *ref.halves())]
    c, u = jackknife(*figs)
    agreement, agreement_u = c["psnr"], u["psnr"]
    worst_mse = max(c["mse"], 0.0) + u["mse"]
    floor = math.inf if worst_mse == 0 else 10 * math.log10(255.0 ** 2 / worst_mse)
    r = ref.image.astype(np.float64)
    rel_mse = float(np.mean((mean - r) ** 2 / (r ** 2 + 0.01)))

    mi_rgb, mi_ids, mi_prims = trace_pixel_centres(scene, frame, width, height)
    diff = np.abs(centre["color"].astype(np.float64) - mi_rgb).max(axis=-1)
    # A pixel centre on a fold or crossing inside one object can fall on either triangle by a
    # float margin; where the two renderers picked different triangles the pixel is on an edge.
    inside = (_interior(centre["object_id"]) & _interior(centre["light_mask"])
              & (mi_ids == centre["object_id"]) & (mi_prims == centre["prim_id"]))
    interior_err = float(diff[inside].max()) if inside.any() else float("nan")
    match = float(np.mean(diff <= 1e-4))
    visible = float(np.mean((mi_ids > 0) & (centre["object_id"] > 0)))
    return Agreement(scene.name, frame, width, height, agreement, rel_mse, interior_err, int(inside.sum()),
                     match, ref.noise_psnr_db, ref.spp, ref.seconds, cached, samples, raster_s,
                     single_sample=bool(spp_gl == 1 and (match >= 0.99 or scene.desc.transport == "path")),
                     transport=scene.desc.transport, reference_se_bound_lsb=ref.bound_lsb,
                     reference_se_p999_lsb=ref.se_p999_lsb, reference_se_max_lsb=ref.se_max_lsb,
                     reference_over_bound=ref.over_bound, reference_spp_max=ref.spp_max,
                     reference_spp_needed=ref.spp_needed, visible_fraction=visible, agreement_u_db=agreement_u, agreement_floor_db=floor,
                     reference_rule="per_pixel" if target_noise_db > 0 else "figures")


# -- agreement of a scene -------------------------------------------------------------------------------
@_deterministic
def agreement_task(ctx: Context, scene_spec: str, w: int, h: int, samples: int, ref_settings: dict,
                   display_settings: dict, key: str, path: str, deps=()) -> dict:
    from references import ReferenceCache

    from study.engine.agreement import check_agreement
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with store.lock(key):
        data = store.load_record(Path(path), key)
        if data is None:
            cache = ReferenceCache(Path(ctx.cache_root))
            a = check_agreement(scene, w, h, samples=samples, cache=cache, progress=False,
                                display=display_of(cache, scene, 0, w, h, display_settings),
                                **_agreement_settings(ref_settings))
            data = store.save_record(Path(path), key, a.as_dict())
            computed = True
        else:
            computed = False
    return {"kind": "agreement", "key": key, "data": data, "computed": computed}


def _agreement_settings(ref_settings: dict) -> dict:
    # one frame, rendered whole: reuse across frames (references.reuse) does not apply
    return {k: v for k, v in ref_settings.items() if k not in ("reuse", "reuse_since")}

