"""The diffusion policy's image of Push-T: its checks, its frame and its colour classes.

LeRobot's diffusion policy observes gym-pusht as ``obs_type="pixels_agent_pos"``: a 96 x 96 RGB
image and the agent's position. `check_pixels` and `check_observation` refuse malformed ones.

Frames. World coordinates are the environment's: ``[0, 512]`` on both axes, y downwards, as its
actions and ``agent_pos`` are. The renderer draws the world on a 512 x 512 screen and shrinks it
to the observed image by bilinear sampling, so pixel ``(row i, column j)`` of an N x N image is
the world point ``((j + 0.5) s - 0.5, (i + 0.5) s - 0.5)`` with ``s = 512 / N``
(`pixel_to_world`, and its inverse `world_to_pixel`).

Colours. Every pixel is unmixed into the fractions of the classes the renderer draws with
(`class_fractions`, `CLASSES`, `PALETTE`): a pixel on an edge mixes two. The pose fits of
`probaff.experiments.pusht.perception` read these fractions.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from probaff.errors import InputError

__all__ = [
    "CLASSES",
    "FRAME_SIZE",
    "PALETTE",
    "WORLD_SIZE",
    "check_observation",
    "check_pixels",
    "class_fractions",
    "pixel_to_world",
    "world_to_pixel",
]

FRAME_SIZE = 96
"""Side of the diffusion policy's observed image (px)."""
WORLD_SIZE = 512.0
"""Side of the environment's world, the range of its actions and positions (world units)."""
CLASSES = ("background", "goal", "block", "agent")
"""What a pixel can show, in the order of `class_fractions`' last axis."""
PALETTE: Mapping[str, tuple[tuple[int, int, int], ...]] = {
    "background": ((255, 255, 255), (211, 211, 211)),
    "goal": ((144, 238, 144),),
    "block": ((143, 163, 184), (119, 136, 153)),
    "agent": ((65, 105, 225), (78, 126, 255)),
}
"""The renderer's RGB colours of each class: the floor and the walls; the goal region; the
block's face and rim; the pusher's rim and face."""


def check_pixels(pixels: Any, name: str = "pixels") -> np.ndarray:
    """The image, checked: an N x N x 3 uint8 RGB array.

    Args:
        pixels: The image (row i, column j, channel RGB).
        name: Its name in the error message.

    Returns:
        The same image as an ndarray.

    Raises:
        InputError: If it is not an array, not uint8, not three channels or not square.
    """
    if not isinstance(pixels, np.ndarray):
        raise InputError(
            f"{name} must be a numpy array of shape (96, 96, 3) and dtype uint8, as "
            f"obs_type='pixels_agent_pos' returns it; got {type(pixels).__name__}."
        )
    if pixels.dtype != np.uint8:
        raise InputError(
            f"{name} must have dtype uint8 (RGB values 0-255, as the environment renders them), "
            f"got {pixels.dtype}; pass the observation's image unconverted."
        )
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise InputError(
            f"{name} must have three RGB channels, shape (H, W, 3), got shape {pixels.shape}; "
            "pass the image of obs_type='pixels_agent_pos', not a grey or RGBA one."
        )
    if pixels.shape[0] != pixels.shape[1] or pixels.shape[0] < 16:
        raise InputError(
            f"{name} must be a square image of at least 16 x 16 (the environment's default is "
            f"{FRAME_SIZE} x {FRAME_SIZE}), got {pixels.shape[0]} x {pixels.shape[1]}."
        )
    return pixels


def check_observation(obs: Any, size: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The image and agent position of a ``pixels_agent_pos`` observation, checked.

    Args:
        obs: The observation dict, ``{"pixels": (N, N, 3) uint8, "agent_pos": (2,)}``.
        size: The image side it must have (None: any square side).

    Returns:
        ``(pixels, agent_pos)``: the (N, N, 3) uint8 image and the (2,) float agent position
        (world units).

    Raises:
        InputError: If it is not a mapping, lacks ``pixels`` or ``agent_pos``, or either is
            malformed (see `check_pixels`).
    """
    if not isinstance(obs, Mapping):
        raise InputError(
            "obs must be the observation dict of obs_type='pixels_agent_pos' with keys 'pixels' "
            f"and 'agent_pos', got {type(obs).__name__}."
        )
    missing = [k for k in ("pixels", "agent_pos") if k not in obs]
    if missing:
        raise InputError(
            f"obs lacks {missing} (it has {sorted(map(str, obs))}); make the environment with "
            "obs_type='pixels_agent_pos', which observes the image and the agent's position."
        )
    pixels = check_pixels(obs["pixels"], "obs['pixels']")
    if size is not None and pixels.shape[:2] != (size, size):
        raise InputError(
            f"obs['pixels'] must be {size} x {size} like the frames the scene was perceived "
            f"from, got {pixels.shape[0]} x {pixels.shape[1]}; keep the environment's "
            "observation_width and observation_height."
        )
    agent = np.asarray(obs["agent_pos"], dtype=float)
    if agent.shape != (2,) or not np.all(np.isfinite(agent)):
        raise InputError(
            f"obs['agent_pos'] must be two finite numbers (world units), got {obs['agent_pos']!r}."
        )
    return pixels, agent


def pixel_to_world(rows: np.ndarray, cols: np.ndarray, size: int = FRAME_SIZE) -> np.ndarray:
    """World points of image pixels (the renderer's bilinear sample points).

    Args:
        rows: (...) row indices i (may be fractional).
        cols: (...) column indices j, broadcast against `rows`.
        size: The image's side N.

    Returns:
        (..., 2) world ``(x, y)``.
    """
    s = WORLD_SIZE / size
    x = (np.asarray(cols, dtype=float) + 0.5) * s - 0.5
    y = (np.asarray(rows, dtype=float) + 0.5) * s - 0.5
    return np.stack(np.broadcast_arrays(x, y), axis=-1)


def world_to_pixel(points: np.ndarray, size: int = FRAME_SIZE) -> np.ndarray:
    """Image coordinates ``(column j, row i)`` of world points (the inverse of `pixel_to_world`).

    Args:
        points: (..., 2) world ``(x, y)``.
        size: The image's side N.

    Returns:
        (..., 2) fractional ``(j, i)``.
    """
    return (np.asarray(points, dtype=float) + 0.5) * (size / WORLD_SIZE) - 0.5


def _palette() -> tuple[np.ndarray, np.ndarray]:
    colours, labels = [], []
    for k, name in enumerate(CLASSES):
        for colour in PALETTE[name]:
            colours.append(colour)
            labels.append(k)
    return np.asarray(colours, dtype=float), np.asarray(labels)


_COLOURS, _LABELS = _palette()
_PAIRS = np.array([(p, q) for p in range(len(_COLOURS)) for q in range(p, len(_COLOURS))])


def class_fractions(pixels: np.ndarray) -> np.ndarray:
    """Per pixel, the fraction of each class (`CLASSES`) it shows.

    Each pixel's colour is explained as the mix of two palette colours (`PALETTE`) nearest to
    it in RGB: a pixel on an edge is the renderer's bilinear mix of the two sides.

    Args:
        pixels: (N, N, 3) uint8 RGB image.

    Returns:
        (N, N, 4) fractions summing to 1 over the last axis.

    Raises:
        InputError: If `pixels` is malformed (`check_pixels`).
    """
    img = check_pixels(pixels).astype(float)
    c = img.reshape(-1, 1, 3)
    p = _COLOURS[_PAIRS[:, 0]][None]
    q = _COLOURS[_PAIRS[:, 1]][None]
    d = p - q
    denom = np.maximum(np.sum(d * d, axis=-1), 1e-12)
    t = np.clip(np.sum((c - q) * d, axis=-1) / denom, 0.0, 1.0)  # (P, pairs): weight of p
    err = np.sum((c - (q + t[..., None] * d)) ** 2, axis=-1)
    best = np.argmin(err, axis=1)
    rows = np.arange(len(best))
    w = t[rows, best]
    out = np.zeros((len(best), len(CLASSES)))
    np.add.at(out, (rows, _LABELS[_PAIRS[best, 0]]), w)
    np.add.at(out, (rows, _LABELS[_PAIRS[best, 1]]), 1.0 - w)
    return out.reshape(*img.shape[:2], len(CLASSES))
