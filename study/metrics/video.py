"""ColorVideoVDP (Mantiuk et al., SIGGRAPH 2024; the `cvvdp` package, pinned in pyproject.toml):
a perceptual video metric calibrated on user studies, in JOD (just-objectionable differences; 10 =
no visible difference, each unit down about 75 % of observers preferring the reference).

Input is display-referred: the study's 8-bit sRGB display images (the same the image metrics
judge, study.display), shown on the display model named by the study file. Our linear values are
scene radiance without an absolute scale, so the metric's HDR mode (absolute cd/m^2) would need a
luminance calibration that no scene has; the tone-mapped image is what a player sees.

The base metric needs no downloaded weights (only cvvdp's ML variants fetch models): importing it
sets HF_HUB_OFFLINE so that nothing can be fetched at run time.

Input: uint8 frames only (F x H x W x 3, or one H x W x 3 image), reference and technique of one
shape; anything else is refused with the shape or dtype named.

References
----------
R. K. Mantiuk, P. Hanji, M. Ashraf, Y. Asano, A. Chapiro, "ColorVideoVDP: A visual difference
predictor for image, video and display distortions", ACM Transactions on Graphics 43(4), 2024.
"""
from __future__ import annotations

import os
from functools import lru_cache

import numpy as np

VERSION = "0.5.7"          # pinned; part of every JOD figure's key (study.engine.plan)


def _as_frames(a, what: str) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.uint8:
        raise ValueError(f"{what}: uint8 8-bit display frames expected (F x H x W x 3), got {a.dtype}")
    if a.ndim == 3:
        a = a[None]
    if a.ndim != 4 or a.shape[-1] != 3:
        raise ValueError(f"{what}: frames must be F x H x W x 3, got shape {a.shape}")
    return np.ascontiguousarray(a)


class ColorVideoVDP:
    """ColorVideoVDP on one display model (cvvdp keeps its pyramids per image size).

    Parameters
    ----------
    display : str
        A cvvdp display model name (e.g. 'standard_fhd').
    threads : int, optional
        torch's CPU threads.
    device : {'auto', 'cpu', 'cuda'}
        Where torch runs the metric: 'auto' is CUDA where torch sees a device, else the CPU
        (study files' [video] device; see torch_device).

    Raises
    ------
    ValueError
        If cvvdp does not know the display model, or 'cuda' is asked and torch sees no device.
    """

    def __init__(self, display: str = "standard_fhd", threads: int | None = None, device: str = "cpu"):
        os.environ["HF_HUB_OFFLINE"] = "1"
        import pycvvdp
        import torch
        if threads:
            torch.set_num_threads(int(threads))
        self.display, self._torch = display, torch
        self.device = torch_device(device, torch.cuda.is_available())
        try:
            self._metric = {hm: pycvvdp.cvvdp(display_name=display, heatmap=hm, quiet=True,
                                              device=torch.device(self.device))
                            for hm in (None, "raw")}
        except Exception as exc:      # cvvdp raises its own error types for an unknown display model
            raise ValueError(f"cvvdp display model {display!r}: {exc}") from None

    def jod(self, test8, ref8, fps: float, heatmap: bool = False) -> tuple[float, np.ndarray | None]:
        """JOD of a technique's frames against the reference's.

        Parameters
        ----------
        test8, ref8 : numpy.ndarray
            F x H x W x 3 uint8 frames (or one H x W x 3 image), of one shape.
        fps : float
            The frame rate they are played at (> 0 for a sequence; a single frame is judged as
            an image).
        heatmap : bool
            Also return the per-pixel difference map of the last frame.

        Returns
        -------
        jod : float
            10 = no visible difference, each unit down about 75 % of observers preferring the
            reference.
        map : numpy.ndarray or None
            (H, W) float32, cvvdp's 'raw' map (0 where nothing is visible, rising with the
            predicted visibility; 1 - JOD/10 per pixel), or None without `heatmap`.

        Raises
        ------
        ValueError
            If the frames are not uint8, not F x H x W x 3, differ in shape, or a sequence has no
            frame rate > 0.

        References
        ----------
        Mantiuk et al. 2024, "ColorVideoVDP".
        """
        t, r = _as_frames(test8, "technique"), _as_frames(ref8, "reference")
        if t.shape != r.shape:
            raise ValueError(f"technique frames {t.shape} and reference frames {r.shape} differ in shape")
        if t.shape[0] > 1 and not fps > 0:
            raise ValueError(f"a sequence needs a frame rate > 0, got {fps!r}")
        m = self._metric["raw" if heatmap else None]
        with self._torch.no_grad():
            if t.shape[0] == 1:
                q, stats = m.predict(t[0], r[0], dim_order="HWC")
            else:
                q, stats = m.predict(t, r, dim_order="FHWC", frames_per_second=float(fps))
        hmap = None
        if heatmap:
            hmap = np.asarray(stats["heatmap"][0, 0, -1].float().cpu().numpy(), np.float32)
        return float(q), hmap


def torch_device(device: str, cuda_available: bool) -> str:
    """The torch device a [video] device setting names here: 'auto' -> 'cuda' where torch sees a
    CUDA device, else 'cpu'; 'cpu'; 'cuda' (ValueError where torch sees none).

    Parameters
    ----------
    device : {'auto', 'cpu', 'cuda'}
    cuda_available : bool
        torch.cuda.is_available() in this process.

    Returns
    -------
    str
        'cpu' or 'cuda'.

    Raises
    ------
    ValueError
        An unknown setting, or 'cuda' without a device.
    """
    if device not in ("auto", "cpu", "cuda"):
        raise ValueError(f"[video] device = {device!r}: expected 'auto', 'cpu' or 'cuda'")
    if device == "cuda" and not cuda_available:
        raise ValueError("[video] device = 'cuda': torch sees no CUDA device here (torch.cuda.is_available() "
                         "is False); use 'auto' or 'cpu'")
    return "cuda" if device == "cuda" or (device == "auto" and cuda_available) else "cpu"


@lru_cache(maxsize=4)
def metric(display: str, threads: int | None = None, device: str = "cpu") -> ColorVideoVDP:
    """A process's metric for a display (its construction and torch's import are paid once).

    Parameters
    ----------
    display : str
        A cvvdp display model name.
    threads : int, optional
        torch's CPU threads.
    device : {'auto', 'cpu', 'cuda'}
        Where torch runs it (torch_device).

    Returns
    -------
    ColorVideoVDP
        Kept per (display, threads, device).
    """
    return ColorVideoVDP(display, threads, device)
