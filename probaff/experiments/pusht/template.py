"""The Push-T block's outline as the renderer draws it, for the template fits of perception.

`TeeShape` is the T's outline as perceived: a bar and a stem of four lengths. `tee_distance`
is its signed distance, `tee_fraction` the fraction of an image pixel it covers as the
renderer makes the image (the T drawn on a screen of one world unit per pixel, shrunk
bilinearly to the frame), and `edge_groups` the outline edge nearest each point. Frames: a pose
``(x, y, theta)`` puts the T's frame in the world (`probaff.experiments.pusht.perception`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["TeeShape", "edge_groups", "tee_distance", "tee_fraction"]


@dataclass(frozen=True)
class TeeShape:
    """The T's outline, perceived: a bar and a stem, in world units.

    The T frame has its origin at the middle of the bar's outer edge and its y axis along the
    stem: the bar spans ``[-bar_length / 2, bar_length / 2] x [0, bar_width]``, the stem
    ``[-stem_width / 2, stem_width / 2] x [bar_width, bar_width + stem_length]``.

    Attributes:
        bar_length: Length of the bar (across the stem).
        bar_width: Width of the bar (along the stem).
        stem_width: Width of the stem.
        stem_length: Length of the stem below the bar.
    """

    bar_length: float
    bar_width: float
    stem_width: float
    stem_length: float

    def as_array(self) -> np.ndarray:
        """(4,) ``[bar_length, bar_width, stem_width, stem_length]``."""
        return np.array([self.bar_length, self.bar_width, self.stem_width, self.stem_length])

    def outline(self) -> np.ndarray:
        """(8, 2) the T's corners in its frame, in drawing order (world units)."""
        a, b, c, e = self.as_array() / [2.0, 1.0, 2.0, 1.0]
        return np.array(
            [[-a, 0], [a, 0], [a, b], [c, b], [c, b + e], [-c, b + e], [-c, b], [-a, b]],
            dtype=float,
        )

    def area(self) -> float:
        """The T's area (world units squared)."""
        return float(self.bar_length * self.bar_width + self.stem_width * self.stem_length)

    def centroid(self) -> np.ndarray:
        """(2,) the T's centre of area in its frame."""
        bar = self.bar_length * self.bar_width
        stem = self.stem_width * self.stem_length
        y = (bar * self.bar_width / 2 + stem * (self.bar_width + self.stem_length / 2)) / (
            bar + stem
        )
        return np.array([0.0, y])


def tee_distance(params: np.ndarray, dims: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Signed distance (P,) of world `points` (P, 2) to the T's outline, negative inside.

    The T is at pose `params` (3,) with lengths `dims` (4,); distances in world units.
    """
    x, y, theta = params
    a, b, c, e = np.abs(dims)
    co, si = math.cos(theta), math.sin(theta)
    dx, dy = points[:, 0] - x, points[:, 1] - y
    u = co * dx + si * dy  # the T's frame
    v = -si * dx + co * dy
    au = np.abs(u)
    # the stem reaches into the bar, so that the union's inside has no seam
    sd_bar = _box_distance(au - a / 2, np.abs(v - b / 2) - b / 2)
    stem_half = (b / 2 + e) / 2
    sd_stem = _box_distance(au - c / 2, np.abs(v - (b / 2 + stem_half)) - stem_half)
    return np.asarray(np.minimum(sd_bar, sd_stem))


_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
"""Offsets of a sample point's four nearest screen pixel centres from the first."""


def tee_fraction(
    params: np.ndarray, dims: np.ndarray, rim: float, points: np.ndarray, ramp: float
) -> np.ndarray:
    """The T's drawn fraction at world `points`: (P,) for pose `params` (3,) and `dims` (4,).

    The renderer draws the T on its screen of one world unit per pixel, lighting a pixel
    whose centre lies inside (the drawn colour reaching `rim` beyond the outline), and shrinks
    the screen bilinearly: an image pixel is the bilinear mix of the four screen pixels around
    its sample point. So is the model, with each screen pixel's inside test softened into a
    step `ramp` wide. An edge is then placed to within the screen pixel it crosses, and no
    finer, which is all the image tells. A ramp wider than a screen pixel (the coarse fits)
    blurs more than the mix: there the step is taken at the sample point itself, a quarter of
    the work.
    """
    if ramp > 1.0:
        sd = tee_distance(params, dims, points) - rim
        return np.clip(0.5 - sd / ramp, 0.0, 1.0)
    base = np.floor(points)
    frac = points - base
    corners = (base[None] + _CORNERS[:, None]).reshape(-1, 2)
    sd = tee_distance(params, dims, corners).reshape(4, -1) - rim
    lit = np.clip(0.5 - sd / ramp, 0.0, 1.0)
    fx, fy = frac[:, 0], frac[:, 1]
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    return np.asarray((weights * lit).sum(0))


def _box_distance(qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
    return outside + np.minimum(np.maximum(qx, qy), 0.0)


def edge_groups(pose: np.ndarray, shape: TeeShape, points: np.ndarray) -> np.ndarray:
    """(P,) index of the outline edge nearest each world point, for the T at `pose`."""
    x, y, theta = pose
    co, si = math.cos(theta), math.sin(theta)
    dx, dy = points[:, 0] - x, points[:, 1] - y
    local = np.stack([co * dx + si * dy, -si * dx + co * dy], axis=-1)
    a = shape.outline()
    b = np.roll(a, -1, axis=0)
    d = b - a
    t = np.clip(
        np.einsum("pkj,kj->pk", local[:, None] - a[None], d) / np.sum(d * d, axis=1), 0.0, 1.0
    )
    nearest = a[None] + t[..., None] * d[None]
    return np.asarray(np.argmin(np.linalg.norm(local[:, None] - nearest, axis=-1), axis=1))
