"""Pinhole camera shared by the raster and the reference (OpenGL convention: looks down -z).

Image coordinates are in pixels, origin at the top-left corner, y down; pixel (x, y) covers
[x, x+1) x [y, y+1). A jitter offset (ox, oy) moves the sample of every pixel from its centre to
(x + 0.5 + ox, y + 0.5 + oy); it is a pure NDC shift applied after projection (thesis Appendix B).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def look_at(position, target, up) -> np.ndarray:
    """Camera-to-world matrix; camera looks down its -z axis, +y is up, +x is right."""
    p, t, u = (np.asarray(a, float) for a in (position, target, up))
    f = t - p
    f /= np.linalg.norm(f)
    r = np.cross(f, u)
    if np.linalg.norm(r) < 1e-12:
        raise ValueError(f"camera up {tuple(u)} is parallel to the view direction")
    r /= np.linalg.norm(r)
    u2 = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, u2, -f, p
    return m


@dataclass(frozen=True)
class CameraState:
    to_world: np.ndarray   # 4x4 camera-to-world
    yfov_deg: float
    near: float
    far: float
    width: int
    height: int

    @property
    def position(self) -> np.ndarray:
        return self.to_world[:3, 3]

    @property
    def tan_half(self) -> tuple[float, float]:
        ty = np.tan(np.radians(self.yfov_deg) / 2)
        return ty * self.width / self.height, ty

    def view(self) -> np.ndarray:
        return np.linalg.inv(self.to_world)

    def projection(self, jitter=(0.0, 0.0)) -> np.ndarray:
        """OpenGL clip matrix with the jitter as an NDC shift (image y is down, NDC y is up)."""
        tx, ty = self.tan_half
        n, f = self.near, self.far
        p = np.zeros((4, 4))
        p[0, 0], p[1, 1] = 1 / tx, 1 / ty
        p[2, 2], p[2, 3] = -(f + n) / (f - n), -2 * f * n / (f - n)
        p[3, 2] = -1.0
        shift = np.eye(4)
        shift[0, 3] = -2.0 * jitter[0] / self.width
        shift[1, 3] = 2.0 * jitter[1] / self.height
        return shift @ p

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 3) -> unjittered image positions (N, 2) and linear view depth (N,)."""
        pc = (np.c_[points, np.ones(len(points))] @ self.view().T)[:, :3]
        depth = -pc[:, 2]
        tx, ty = self.tan_half
        x = (pc[:, 0] / depth / tx + 1) * 0.5 * self.width
        y = (1 - pc[:, 1] / depth / ty) * 0.5 * self.height
        return np.stack([x, y], -1), depth

    def ray_directions(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """World directions (unnormalised, unit view-axis component) through image positions."""
        tx, ty = self.tan_half
        d = np.stack([(2 * xs / self.width - 1) * tx, (1 - 2 * ys / self.height) * ty,
                      -np.ones_like(xs)], -1)
        return d @ self.to_world[:3, :3].T
