"""One frame's reference (references.render makes it): its mean image, per-pixel standard errors
and sample counts, and the figures of its convergence."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import settings as S
from .estimates import fold

LSB = 1.0 / 255.0


class ReferenceError(RuntimeError):
    pass


@dataclass
class Reference:
    image: np.ndarray        # (H, W, 3) float32 linear HDR, mean over all samples
    stderr: np.ndarray       # (H, W, 3) float32 per-pixel standard error of the mean (linear)
    spp: int                 # mean samples per pixel, rounded
    passes: int              # uniform pilot passes
    seconds: float
    noise_psnr_db: float     # secondary: display-domain noise of the mean, as PSNR
    key: str = ""            # content hash the cache filed it under
    spp_map: np.ndarray | None = None          # (H, W) samples per pixel
    display_stderr: np.ndarray | None = None   # (H, W, 3) display-domain SE (1 = full scale)
    bound_lsb: float = S.SE_BOUND_LSB          # the per-pixel bound it was rendered to
    rounds: int = 0                            # adaptive rounds after the pilot
    display_floor: np.ndarray | None = None    # (H, W, 3) the unseen-feature part of display_stderr
    half_delta: np.ndarray | None = None       # (H, W, 3) linear: half A = image + delta, B = image - delta
    spp_needed: int = 0     # what the worst pixel over the bound at the cap would take (0: none)
    held_out: bool = False  # the value is the mean of samples no stopping decision saw
    sample_lo: np.ndarray | None = None   # (H, W, 3) each pixel's smallest sample (what a later frame's floor reads)
    sample_hi: np.ndarray | None = None   # and largest
    reused: np.ndarray | None = None      # (H, W) bool: the previous frame's estimate (references.reuse)
    _history: list = field(default_factory=list, repr=False)

    @property
    def noise_history(self):
        """(mean spp, seconds, noise PSNR dB, max SE LSB) after each pass or round."""
        return self._history

    def halves(self) -> tuple[np.ndarray, np.ndarray]:
        """The two independent half-sample references (linear HDR) whose mean is `image`: what a
        figure's reference uncertainty is estimated from (study.metrics.uncertainty)."""
        if self.half_delta is None:
            raise ReferenceError("this reference keeps no half-sample split")
        return self.image + self.half_delta, self.image - self.half_delta

    @property
    def se_lsb(self) -> np.ndarray:
        """(H, W) display-domain SE of the worst channel, in 8-bit LSB."""
        return fold(np.maximum, self.display_stderr) / LSB

    @property
    def spp_mean(self) -> float:
        return float(self.spp_map.mean())

    @property
    def traced(self) -> int:
        """Samples traced for this frame: the reused pixels' were traced for an earlier one."""
        spp = self.spp_map.astype(np.int64)
        return int(spp.sum() if self.reused is None else spp[~self.reused].sum())

    @property
    def spp_max(self) -> int:
        return int(self.spp_map.max())

    @property
    def se_p999_lsb(self) -> float:
        return float(np.percentile(self.se_lsb, 99.9))

    @property
    def se_max_lsb(self) -> float:
        return float(self.se_lsb.max())

    @property
    def floor_bound(self) -> int:
        """Pixels whose reported SE is the unseen-feature floor, not the spread of their samples."""
        if self.display_floor is None:
            return 0
        return int(np.sum(fold(np.logical_or, (self.display_floor >= self.display_stderr) & (self.display_stderr > 0))))

    @property
    def over_bound(self) -> int:
        """Pixels whose SE is still above the bound (they hit the sample cap)."""
        return int(np.sum(self.se_lsb > self.bound_lsb * (1 + 1e-5)))   # float32 storage slack
