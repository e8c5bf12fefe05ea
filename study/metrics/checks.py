"""What the metrics can judge, checked up front: a metric refuses a pair it cannot judge with one
line that names the image, the problem and what it expected, as scikit-image's
`structural_similarity` refuses float input without a `data_range` and pbrt-v4's `imgtool diff`
refuses images of different sizes.

The checks cost at most one min and one max per float image (numpy reductions, no temporaries):
both propagate NaN, and a finite min and max mean no Inf, so together they are the NaN/Inf check
and the range check at once. 8-bit images need no pass at all. The NaN/Inf count in a message is
computed only once an image has been refused.
"""
from __future__ import annotations

import math

import numpy as np


def as_array(metric: str, name: str, a) -> np.ndarray:
    """`a` as a numpy array of real numbers.

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    name : str
        What the image is (``"reference"``, ``"test image"``), for the message.
    a : array_like
        The image.

    Returns
    -------
    numpy.ndarray
        `a` itself when it is one already (no copy).

    Raises
    ------
    ValueError
        If `a` is None or its dtype is not an unsigned/signed integer or a float (bool, complex,
        object, strings).
    """
    if a is None:
        raise ValueError(f"{metric}: the {name} is missing (None)")
    a = np.asarray(a)
    if a.dtype.kind not in "uif":
        raise ValueError(f"{metric}: the {name} has dtype {a.dtype}; an image of real numbers is needed")
    return a


def same_shape(metric: str, a: np.ndarray, b: np.ndarray, names=("reference", "test image")) -> None:
    """Refuse two images of different shapes, naming both.

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    a, b : numpy.ndarray
        The two images.
    names : tuple of str
        What `a` and `b` are, for the message.

    Raises
    ------
    ValueError
        If the shapes differ.
    """
    if a.shape != b.shape:
        raise ValueError(f"{metric} needs two images of one shape: the {names[0]} is {_shape(a)}, "
                         f"the {names[1]} {_shape(b)}")


def rgb(metric: str, a: np.ndarray, b: np.ndarray, names=("reference", "test image")) -> None:
    """Refuse a pair that is not two H x W x 3 images of one shape, naming both shapes.

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    a, b : numpy.ndarray
        The two images.
    names : tuple of str
        What `a` and `b` are, for the message.

    Raises
    ------
    ValueError
        If the shapes differ or are not H x W x 3.
    """
    same_shape(metric, a, b, names)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"{metric} needs two H x W x 3 images of one shape, got {_shape(a)} and {_shape(b)}")


def same_kind(metric: str, a: np.ndarray, b: np.ndarray, expected: str) -> None:
    """Refuse an 8-bit image judged against a float one (their values are on different scales).

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    a, b : numpy.ndarray
        The reference and the test image.
    expected : str
        The input the metric expects, for the message.

    Raises
    ------
    ValueError
        If one image is integer and the other float.
    """
    if (a.dtype.kind == "f") != (b.dtype.kind == "f"):
        raise ValueError(f"{metric}: the reference is {a.dtype} and the test image {b.dtype}; "
                         f"it expects {expected}, both of one kind")


def finite_span(metric: str, name: str, a: np.ndarray) -> tuple[float, float]:
    """(min, max) of a float image, refusing NaN and Inf.

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    name : str
        What the image is, for the message.
    a : numpy.ndarray
        A non-empty float image.

    Returns
    -------
    tuple of float
        The smallest and the largest value.

    Raises
    ------
    ValueError
        If `a` is empty or holds NaN or Inf (the message gives their number).
    """
    if a.size == 0:
        raise ValueError(f"{metric}: the {name} is empty ({_shape(a)})")
    lo, hi = float(np.min(a)), float(np.max(a))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{metric}: the {name} holds {int(np.count_nonzero(~np.isfinite(a)))} NaN/Inf values")
    return lo, hi


def positive(metric: str, name: str, v) -> float:
    """A finite number > 0 (a data range, a sigma, pixels per degree) as a float.

    Parameters
    ----------
    metric : str
        The metric's name, for the message.
    name : str
        The parameter's name, for the message.
    v : float
        The value.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        If `v` is not a finite number > 0.
    """
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{metric}: {name} must be a number > 0, got {v!r}") from None
    if not (math.isfinite(f) and f > 0):
        raise ValueError(f"{metric}: {name} must be a finite number > 0, got {v!r}")
    return f


def _shape(a: np.ndarray) -> str:
    return "x".join(str(n) for n in a.shape) if a.ndim else "a scalar"
