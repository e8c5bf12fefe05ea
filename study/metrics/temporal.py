"""Temporal instability (Oliveros 2018, §3.9): the RMS error, in 8-bit units, of a technique's
frame-to-frame differences against the reference's, which flicker and ghost trails raise.
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import checks
class TemporalInstability:
    """RMS (8-bit units) of the error of frame-to-frame differences against the reference's.

    Flicker and ghost trails raise it, a stable sequence that follows the reference keeps it low.
    Fed one (reference, technique) pair of 8-bit frames at a time, in sequence order (`add`);
    `value` gives the figure.

    Attributes
    ----------
    frames : int
        Frames added so far.
    """

    def __init__(self):
        self.frames, self._acc, self._n, self._prev = 0, 0.0, 0, None

    def add(self, ref8: np.ndarray, x8: np.ndarray) -> None:
        """Add the next frame of the sequence.

        Parameters
        ----------
        ref8, x8 : numpy.ndarray
            The reference's and the technique's frame, uint8, of one shape (that of the frames
            added before).

        Raises
        ------
        ValueError
            If a frame is not uint8, the two differ in shape, or their shape is not the earlier
            frames'.
        """
        # in integers: 8-bit differences of differences (|d| <= 510) squared and summed exactly,
        # the same value as in float64 at a sixth of the time
        r, x = np.asarray(ref8), np.asarray(x8)
        if r.dtype != np.uint8 or x.dtype != np.uint8:
            raise ValueError(f"temporal instability: 8-bit frames expected, got {r.dtype} and {x.dtype}")
        checks.same_shape("temporal instability", r, x, ("reference frame", "technique frame"))
        if self._prev is not None and r.shape != self._prev[0].shape:
            raise ValueError(f"temporal instability: frame {self.frames} is {r.shape}, "
                             f"the earlier frames {self._prev[0].shape}")
        r, x = r.astype(np.int32), x.astype(np.int32)
        if self._prev is not None:
            d = (x - self._prev[1]) - (r - self._prev[0])
            self._acc += float(np.sum(d * d, dtype=np.int64))
            self._n += d.size
        self._prev = (r, x)
        self.frames += 1

    def value(self) -> float:
        """The figure: RMS of the differences' errors, in 8-bit units.

        Returns
        -------
        float
            NaN for fewer than two frames.
        """
        return math.sqrt(self._acc / self._n) if self._n else math.nan


def temporal_instability(ref_seq: list[np.ndarray], x_seq: list[np.ndarray]) -> float:
    """`TemporalInstability` of two whole sequences.

    Parameters
    ----------
    ref_seq, x_seq : list of numpy.ndarray
        The reference's and the technique's 8-bit frames (uint8, one shape), in sequence order.

    Returns
    -------
    float
        The RMS in 8-bit units; NaN for fewer than two frames.

    Raises
    ------
    ValueError
        If the sequences differ in length, or as `TemporalInstability.add`.
    """
    if len(ref_seq) != len(x_seq):
        raise ValueError(f"temporal instability: {len(ref_seq)} reference frames and {len(x_seq)} technique frames")
    acc = TemporalInstability()
    for r, x in zip(ref_seq, x_seq):
        acc.add(r, x)
    return acc.value()
