"""The precision rule's settings (a study file's [precision]; study.engine.precision applies them).
Their defaults: study.config.defaults.PRECISION."""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import defaults as D


# The figures that have a tolerance (study.metrics.uncertainty.TOLERANCE_OF), so can set a bound.
# A ghosting test's means over its frames are figures of their own ("mse_mean", ...): exempting the
# per-frame figure leaves its mean setting the bound.
_PER_FRAME = ("mse", "rmsd", "psnr", "snr", "ssim", "ssim_volume", "flip_ldr", "flip_hdr", "relmse_hdr")
EXEMPTABLE = (*_PER_FRAME, "temporal", *(f + "_mean" for f in _PER_FRAME))


@dataclass(frozen=True)
class Exemption:
    """Figures that are printed with their uncertainty but set no test's bound: `figures` of
    `column` on `tests` of `scenes` (column None: every one; each tuple empty: every one)."""
    column: str | None = None
    figures: tuple = ()      # metrics: 'mse', 'psnr', 'ssim', 'flip_ldr', ..., 'temporal'
    tests: tuple = ()        # protocol names
    scenes: tuple = ()       # built-in scenes' names, scene files' resolved paths

    def __post_init__(self):
        for f in ("figures", "tests", "scenes"):
            object.__setattr__(self, f, tuple(getattr(self, f)))

    def covers(self, scene: str, test: str, column: str, figure: str) -> bool:
        """Whether this exemption covers `figure` of `column` on `test` of `scene` (a built-in's
        name or a scene file's path, as a run names it)."""
        if scene.endswith((".toml", ".json")):
            from pathlib import Path
            scene = str(Path(scene).resolve())
        return (self.column in (None, column) and (not self.figures or figure in self.figures)
                and (not self.tests or test in self.tests) and (not self.scenes or scene in self.scenes))


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
    # Figures that set no bound where a whole column still does (Exemption): a spatial-only
    # column's per-frame MSE on a scene made to test temporal stability, say.
    exemptions: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "exempt", tuple(self.exempt))
        object.__setattr__(self, "exemptions", tuple(self.exemptions))

    def exempts(self, scene: str, test: str, column: str, figure: str) -> bool:
        """Whether a figure sets no precision bound: its column is exempt, or an exemption covers it.

        Parameters
        ----------
        scene, test : str
            The scene as the run names it (a built-in's name, a scene file's path) and the test's
            protocol name.
        column, figure : str
            The column's label and the figure's metric ('mse', 'psnr', ..., 'temporal').
        """
        return column in self.exempt or any(e.covers(scene, test, column, figure) for e in self.exemptions)

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
