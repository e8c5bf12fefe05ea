"""The Gaussian windows of SSIM's two forms (study.metrics.ssim): scikit-image's radius rule, MATLAB's
filter size, and the 3x3 channel mixing that the volume form's Gaussian along the channel axis reduces to.
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import filters as jf

SIGMA = 1.5
SKIMAGE_TRUNCATE = 3.5


def skimage_radius(sigma: float = SIGMA) -> int:
    """Radius of scikit-image's Gaussian window, int(truncate * sigma + 0.5), truncate 3.5.

    Parameters
    ----------
    sigma : float
        The Gaussian's standard deviation in pixels.

    Returns
    -------
    int
        5 for sigma 1.5 (an 11-tap window).
    """
    return int(SKIMAGE_TRUNCATE * sigma + 0.5)


def matlab_radius(sigma: float = SIGMA) -> int:
    """Radius of MATLAB ssim's Gaussian window, ceil(3 sigma) (FilterSize 2 ceil(3 sigma) + 1).

    Parameters
    ----------
    sigma : float
        The Gaussian's standard deviation in pixels.

    Returns
    -------
    int
        5 for sigma 1.5 (an 11-tap window).
    """
    return int(math.ceil(3 * sigma))


def channel_mixing(weights: np.ndarray, channels: int = 3) -> np.ndarray:
    """The 1-D filter along the channel axis, 'replicate' padding, as a channels x channels matrix.

    Parameters
    ----------
    weights : numpy.ndarray
        The filter's taps (odd length, centre in the middle).
    channels : int
        Number of channels.

    Returns
    -------
    numpy.ndarray
        M with M[c, c'] the weight channel c' gets in output channel c.
    """
    r = len(weights) // 2
    m = np.zeros((channels, channels))
    for c in range(channels):
        for k in range(-r, r + 1):
            m[c, jf.border_index(c + k, channels, "clamp")] += weights[k + r]
    return m
