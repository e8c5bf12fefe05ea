"""Comparison figures with insets, as in the thesis: the reference and each technique side by side,
and under them zoomed crops of the regions where the techniques differ most.

The regions come from the techniques' error maps (e.g. 1 - SSIM or FLIP, H x W, larger = worse):
the score of a pixel is the spread of the error across techniques (max - min), so a region every
technique gets equally wrong is not chosen over one where they disagree; with a single technique
(or where all agree everywhere) it is that error itself. Windows are square; each one is the
window of largest summed score that overlaps none chosen before it.
"""
from __future__ import annotations

import io

import numpy as np

INSET_COLOURS = ("#e41a1c", "#377eb8", "#4daf4a", "#ff7f00", "#984ea3", "#a65628")


def default_inset_size(height: int, width: int) -> int:
    """A fifth of the short side (at least 8 pixels, at most the short side)."""
    short = min(height, width)
    return max(1, min(short, max(8, short // 5)))


def _score(error_maps: dict[str, np.ndarray]) -> np.ndarray:
    stack = np.stack([np.nan_to_num(np.asarray(e, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
                      for e in error_maps.values()])
    if len(stack) >= 2:
        spread = stack.max(0) - stack.min(0)
        if spread.max() > 0:
            return spread
    return np.abs(stack).mean(0)


def inset_regions(error_maps: dict[str, np.ndarray], n: int = 2, size: int | None = None
                  ) -> list[tuple[int, int, int, int]]:
    """Up to n non-overlapping squares (x, y, w, h) in pixels, strongest first."""
    if not error_maps:
        raise ValueError("inset_regions: no error maps given")
    shapes = {np.shape(e) for e in error_maps.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"inset_regions: error maps must share one H x W shape, got {sorted(shapes)}")
    score = _score(error_maps)
    h, w = score.shape
    s = default_inset_size(h, w) if size is None else int(size)
    if not 1 <= s <= min(h, w):
        raise ValueError(f"inset_regions: inset size {s} does not fit a {w}x{h} image")
    # Summed score of every s x s window (top-left at (x, y)) from an integral image.
    ii = np.zeros((h + 1, w + 1))
    ii[1:, 1:] = score.cumsum(0).cumsum(1)
    win = ii[s:, s:] - ii[:-s, s:] - ii[s:, :-s] + ii[:-s, :-s]
    taken = np.zeros(win.shape, bool)
    out = []
    for _ in range(max(0, n)):
        if taken.all():
            break
        masked = np.where(taken, -np.inf, win)
        y, x = np.unravel_index(int(np.argmax(masked)), masked.shape)
        # argmax takes the top-left one of tied windows: centre it on the error it holds instead
        # when that keeps all of it and stays clear of the windows already chosen.
        part = score[y:y + s, x:x + s]
        if part.sum() > 0:
            cy, cx = (np.indices(part.shape) * part).reshape(2, -1).sum(1) / part.sum()
            ny = int(np.clip(round(y + cy - (s - 1) / 2), 0, h - s))
            nx = int(np.clip(round(x + cx - (s - 1) / 2), 0, w - s))
            if not taken[ny, nx] and win[ny, nx] >= win[y, x]:
                y, x = ny, nx
        out.append((int(x), int(y), s, s))
        # Windows overlapping this one start within s - 1 pixels of it on both axes.
        taken[max(0, y - s + 1):y + s, max(0, x - s + 1):x + s] = True
    return out


def _check_images(images: dict, reference: np.ndarray, error_maps: dict) -> tuple[int, int]:
    ref = np.asarray(reference)
    if ref.ndim != 3 or ref.shape[2] != 3 or ref.dtype != np.uint8:
        raise ValueError(f"comparison_figure: reference must be H x W x 3 uint8, got {ref.shape} {ref.dtype}")
    h, w = ref.shape[:2]
    for label, img in images.items():
        img = np.asarray(img)
        if img.shape != ref.shape or img.dtype != np.uint8:
            raise ValueError(f"comparison_figure: image {label!r} is {img.shape} {img.dtype}, "
                             f"the reference {ref.shape} uint8")
    for label, e in error_maps.items():
        if np.shape(e) != (h, w):
            raise ValueError(f"comparison_figure: error map {label!r} is {np.shape(e)}, expected {(h, w)}")
    if not images:
        raise ValueError("comparison_figure: no technique images given")
    return h, w


def comparison_figure(images: dict[str, np.ndarray], reference: np.ndarray, error_maps: dict[str, np.ndarray],
                      n_insets: int = 2, inset_size: int | None = None, reference_label: str = "Reference",
                      captions: dict[str, str] | None = None, column_inches: float = 1.6) -> bytes:
    """PNG of the reference and each technique (columns), full frame on top with the inset squares
    drawn, then one row per inset magnified with nearest-neighbour pixels. A column is
    max(width, 320) figure pixels wide (small images are enlarged, so that the labels stay legible);
    an inset of s pixels fills a column. captions: optional text under a column's full frame (e.g. its PSNR)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    h, w = _check_images(images, reference, error_maps)
    regions = inset_regions(error_maps or {k: np.zeros((h, w)) for k in images}, n_insets, inset_size)
    columns = [(reference_label, np.asarray(reference))] + [(k, np.asarray(v)) for k, v in images.items()]
    ncol, nrow = len(columns), 1 + len(regions)
    title_in = 0.3
    fig = plt.figure(figsize=(column_inches * ncol, title_in + column_inches * (h / w + len(regions))),
                     dpi=max(w, 320) / column_inches)
    grid = fig.add_gridspec(nrow, ncol, height_ratios=[h / w] + [1.0] * len(regions),
                            left=0, right=1, bottom=0, top=1 - title_in / fig.get_figheight(),
                            wspace=0.04, hspace=0.04)
    for c, (label, img) in enumerate(columns):
        ax = fig.add_subplot(grid[0, c])
        ax.imshow(img, interpolation="nearest")
        ax.set_title(label, fontsize=7, pad=2)
        for i, (x, y, sw, sh) in enumerate(regions):
            ax.add_patch(Rectangle((x - 0.5, y - 0.5), sw, sh, fill=False, lw=0.8,
                                   edgecolor=INSET_COLOURS[i % len(INSET_COLOURS)]))
        if captions and label in captions:
            ax.text(0.5, 0.02, captions[label], transform=ax.transAxes, ha="center", va="bottom", fontsize=5,
                    color="white", bbox={"facecolor": "black", "alpha": 0.5, "pad": 1, "lw": 0})
        ax.set_axis_off()
        for r, (x, y, sw, sh) in enumerate(regions, start=1):
            ax = fig.add_subplot(grid[r, c])
            ax.imshow(img[y:y + sh, x:x + sw], interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            for sp in ax.spines.values():
                sp.set_edgecolor(INSET_COLOURS[(r - 1) % len(INSET_COLOURS)])
                sp.set_linewidth(1.2)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


__all__ = ["comparison_figure", "inset_regions", "default_inset_size"]
