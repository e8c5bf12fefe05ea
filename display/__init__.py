"""The display transform (docs/method.md), applied once and identically to every image.

Global Reinhard (2002): Rec.709 luminance L_w, log-average key over the *reference*
L_avg = exp(mean(log(delta + L_w))), scaled L = a / L_avg * L_w, compressed
L_d = L (1 + L / L_white^2) / (1 + L) with L_white in scaled units, RGB scaled by L_d / L_w,
then sRGB-encoded and quantised to 8 bits. The key and white point come from the reference so
the technique being judged cannot move them. (Marín 2015's real-time global Reinhard writes L_white in
unscaled units beside a scaled L; here both are scaled.)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REC709 = np.array([0.2126, 0.7152, 0.0722], np.float64)
KEY_PRESETS = {"low": 0.09, "default": 0.18, "high": 0.36}


def luminance(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(rgb, np.float64) @ REC709


def _round3(x: float) -> float:
    return float(f"{x:.3g}")


@dataclass(frozen=True)
class DisplayTransform:
    log_average: float      # L_avg of the reference, linear units
    white: float            # L_white, scaled units
    key: float = 0.18

    @classmethod
    def from_reference(cls, reference: np.ndarray, key: float = 0.18, delta: float = 1e-4,
                       white: float | None = None) -> "DisplayTransform":
        ref = np.asarray(reference, np.float64)
        if not np.all(np.isfinite(ref)):
            raise ValueError("reference image contains NaN or Inf; cannot derive the display key")
        lw = np.maximum(luminance(ref), 0.0)
        # To 3 significant digits (0.1-0.5 % of exposure, invisible): the reference's own noise
        # moves the log-average by ~1e-5, and a display-space technique (FXAA on text_wall at
        # 1600x900) turned that into 0.036 dB; rounded, references of one frame at different
        # precisions give one transform.
        log_avg = _round3(float(np.exp(np.mean(np.log(delta + lw)))))
        if white is None:   # Reinhard's default: the brightest scaled luminance maps to white
            white = _round3(float(max(key / log_avg * lw.max(), 1e-6)))
        return cls(log_avg, white, key)

    def tonemap(self, rgb: np.ndarray) -> np.ndarray:
        """Linear HDR -> linear display values in [0, 1] (before encoding)."""
        x = np.maximum(np.asarray(rgb, np.float64), 0.0)
        lw = luminance(x)
        l = self.key / self.log_average * lw
        ld = l * (1 + l / self.white ** 2) / (1 + l)
        scale = np.divide(ld, lw, out=np.zeros_like(lw), where=lw > 0)
        return np.clip(x * scale[..., None], 0.0, 1.0)

    def encode(self, rgb: np.ndarray) -> np.ndarray:
        """Display image as floats in [0, 1], sRGB-encoded, not quantised."""
        import colour   # colour-science loads its plotting stack (~1.7 s): only where an image is encoded
        return np.asarray(colour.cctf_encoding(self.tonemap(rgb), function="sRGB"), np.float64)

    def to_8bit(self, rgb: np.ndarray) -> np.ndarray:
        return quantise(self.encode(rgb))

    def output(self, x: np.ndarray, output_space: str):
        """A technique's output as (linear HDR or None, display floats, 8-bit display): an output
        already in display space (FXAA, SMAA) is clipped, not encoded, and has no linear form."""
        if output_space == "display":
            disp = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
            return None, disp, quantise(disp)
        disp = self.encode(x)
        return x, disp, quantise(disp)


def quantise(display: np.ndarray) -> np.ndarray:
    """Display floats in [0, 1] -> 8-bit, rounded to nearest."""
    return np.round(display * 255.0).astype(np.uint8)


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    """PSNR in dB; +inf for identical images."""
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(peak ** 2 / mse)
