"""The precision rule's settings (a study file's [precision]; study.engine.precision applies them).
Their defaults: study.config.defaults.PRECISION."""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import defaults as D


@dataclass(frozen=True)
class Precision:
    rule: str = D.PRECISION["rule"]                       # 'figures' | 'per_pixel'
    psnr_db: float = D.PRECISION["psnr_db"]               # PSNR and SNR, dB
    ssim: float = D.PRECISION["ssim"]                     # SSIM and volume SSIM
    flip: float = D.PRECISION["flip"]                     # FLIP LDR and HDR
    relative: float = D.PRECISION["relative"]             # MSE, RMSD, temporal RMS: a fraction
    relmse: float = D.PRECISION["relmse"]                 # relMSE HDR: a fraction
    start_bound_lsb: float = D.PRECISION["start_bound_lsb"]
    finest_bound_lsb: float = D.PRECISION["finest_bound_lsb"]
    # A test whose figures are within tolerance at the probe rendered once more at the next bound,
    # to measure the drift there too (study.engine.precision).
    confirm: bool = D.PRECISION["confirm"]
    # Column labels whose figures are printed with their uncertainty but set no test's bound: a
    # control that nearly is the reference (the thesis's 128-sample accumulation: MSE ~0.05 on pipe
    # at 320x180) would ask for the finest bound on every scene, 16-64x the samples of the rest.
    exempt: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "exempt", tuple(self.exempt))

    @property
    def tolerances(self) -> dict:
        return {"psnr_db": self.psnr_db, "ssim": self.ssim, "flip": self.flip, "relative": self.relative,
                "relmse": self.relmse}

    def levels(self) -> int:
        """How many times a test's bound can be halved from the start."""
        return max(0, int(math.floor(math.log2(self.start_bound_lsb / self.finest_bound_lsb) + 1e-9)))

    def bound(self, level: int) -> float:
        return self.start_bound_lsb / 2 ** level

    def display_settings(self, base: dict) -> dict:
        """The reference a frame's display transform comes from, under either rule: the probe's
        (study.engine.tasks.display_of)."""
        return {**base, "se_bound_lsb": self.start_bound_lsb, "target_noise_db": 0.0, "held_out": True}

    def settings(self, base: dict, level: int) -> dict:
        """A test's reference settings at a level. The mean-noise target is the per-pixel rule's;
        under the figures' rule the figures decide, from references whose values no stopping
        decision saw (references.estimates: else the figures drift with the bound)."""
        if self.rule == "per_pixel":
            return dict(base)
        return {**base, "se_bound_lsb": self.bound(level), "target_noise_db": 0.0, "held_out": True}
