"""Push-T perception from the diffusion policy's observation: the T's pose read off the image.

LeRobot's diffusion policy observes gym-pusht as ``obs_type="pixels_agent_pos"``: a 96 x 96 RGB
image and the agent's position. This module reads the block's pose ``(x, y, theta)``, with an
uncertainty, off that image alone, and perceives the rest of the scene from the frames too: the
goal region (the green T) and the T's outline. Nothing of the T's geometry or of the goal's
pose is taken from the environment: the T is modelled as what the task calls it, a bar and a
stem of unknown lengths and widths, and those four lengths, the goal's pose and the width of
the block's drawn rim are fitted to the frames (`perceive_scene`).

One idea: colour fractions, then a fitted template. Every pixel is unmixed into the fractions
of the colours the renderer draws with (`class_fractions`; a pixel on an edge mixes two), and a
T is fitted to the block's fraction by least squares, coarse to fine (`perceive_block`): first
with edges ramped over a few world units, then as the renderer makes the image, the T drawn on
its screen of one world unit per pixel and shrunk bilinearly, so that each image pixel mixes the
four screen pixels around its sample point (`tee_fraction`). Its covariance is
the Gauss-Newton (Laplace) one of that fit, scaled by the residual, plus a block jackknife over
the outline's eight edges (the fit again without the pixels nearest each edge): the image
samples the world every 5.3 units, so one edge's pixels err together, which the Laplace
approximation alone, counting every pixel as independent, would miss. The position's precision
also gets that of one sample spacing (a uniform uncertainty over 5.3 units, 1.54 units of
standard deviation): a pixel is a point sample on a ramp one unit wide, so where no sample point
falls on the ramp of one orientation's edges (a T at 45 degrees can show this), the fit has no
slope along their normal, and the Laplace variance alone runs to tens of units for an edge that
the samples still place within one spacing.

One frame pins the T's outline down only to the sampling: the perceived lengths can be off by
a unit or two (the bar's width against the stem's length most). Goal and block share the one
outline, so their relative pose, which decides the coverage, is read with the same one.

Frames. World and image coordinates, the checks of the image and its colour classes are in
`probaff.experiments.pusht.pixels`. A pose is the T's frame in the world: its origin at the
middle of the bar's outer edge, its y axis along the stem towards the stem's foot, and
``theta`` the angle that turns the world's axes onto it (``world = R(theta) @ local + (x, y)``).

Frames where the block cannot be read well enough (hidden under the pusher, mostly out of the
image, or fitted poorly) are not errors: `perceive_block` returns them with a status other than
``"ok"`` and `BlockEstimate.ok` False, and the caller observes again.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from probaff._checks import real_float64
from probaff.errors import InputError
from probaff.experiments.pusht.fitting import (
    fit_least_squares,
    fit_ramped,
    laplace_cov,
    length_cov,
    outline_cov,
)
from probaff.experiments.pusht.pixels import (
    FRAME_SIZE,
    WORLD_SIZE,
    check_pixels,
    class_fractions,
    pixel_to_world,
)
from probaff.experiments.pusht.template import TeeShape, edge_groups, tee_fraction

__all__ = [
    "BlockEstimate",
    "PerceptionOptions",
    "Scene",
    "perceive_block",
    "perceive_scene",
    "refine_scene",
]

_GOAL_RIM = 0.0  # world units: the goal region is filled to its outline, with no rim


@dataclass(frozen=True)
class PerceptionOptions:
    """Settings of the template fits and of the checks that flag a frame.

    Attributes:
        ramps: Edge ramp widths (world units) of the coarse-to-fine fit. Those of one screen
            pixel or less model the renderer: its screen pixels' inside tests, softened by
            the ramp, mixed bilinearly into the image's (`tee_fraction`). On the goal region
            of 40 resets (seeds 0-39) the last two stages (1 and 0.25) cut the goal's mean
            position error from 1.04 to 0.59 world units.
        starts: Starting angles of the block's global search (evenly spaced).
        margin: Pixels around the block's colour that its fit looks at.
        unknown: A pixel whose fraction of an occluding class exceeds this is left out.
        min_visible: Least fraction of the T's expected area that must show its colour.
        max_hidden: Most fraction of the fitted T's area that may lie under the pusher.
        max_rms: Most mismatch of the fit: the summed absolute difference between the
            fitted T's and the image's block fraction, over the fitted T's area.
        max_std_px: Most standard deviation of the position (px of the image).
        max_std_deg: Most standard deviation of the angle (degrees). A T whose edges lie
            along the pixel grid is read to about a degree or two, however long it is looked
            at, so these bounds flag only estimates too uncertain to plan on.
        goal_hidden: Most fraction of the goal region's fitted T that may lie under the block
            or the pusher in every frame before the outline is fitted to the goal region and
            the block together (`perceive_scene`). On 150 resets (seeds 0-149), 82 hid part
            of the goal; fitting those jointly cut the worst goal position error from 4.7 to
            2.4 world units and the worst outline length error from 23.5 to 3.5.
    """

    ramps: tuple[float, ...] = (8.0, 3.0, 1.0, 0.25)
    starts: int = 8
    margin: int = 4
    unknown: float = 0.02
    min_visible: float = 0.5
    max_hidden: float = 0.1
    max_rms: float = 0.15
    max_std_px: float = 2.0
    max_std_deg: float = 5.0
    goal_hidden: float = 0.01

    def __post_init__(self) -> None:
        if not self.ramps or any(not (math.isfinite(r) and r > 0) for r in self.ramps):
            raise InputError(f"PerceptionOptions.ramps must be positive widths, got {self.ramps}.")
        if not (isinstance(self.goal_hidden, int | float) and 0.0 <= self.goal_hidden <= 1.0):
            raise InputError(
                f"PerceptionOptions.goal_hidden must be a fraction in [0, 1], got "
                f"{self.goal_hidden!r}."
            )
        if self.starts < 1 or self.margin < 0:
            raise InputError(
                "PerceptionOptions.starts must be at least 1 and margin at least 0, got "
                f"{self.starts} and {self.margin}."
            )

    @property
    def smooth_ramp(self) -> float:
        """The ramp (world units) at which covariances are read: the last but one of `ramps`.

        The finest stage draws the T on a screen of one world unit per pixel, so its
        residual is flat in a length or a position between two whole units; a ramp of about
        one unit is smooth there (`probaff.experiments.pusht.fitting.length_cov`).
        """
        return self.ramps[-2] if len(self.ramps) > 1 else self.ramps[-1]


@dataclass(frozen=True)
class Scene:
    """What is perceived once per episode: the T's outline, the goal and the block's rim.

    Attributes:
        shape: The T's outline (shared by the goal region and the block).
        goal: (3,) the goal region's pose ``(x, y, theta)`` (world units, radians).
        goal_cov: (3, 3) its covariance (the Laplace approximation of the fit).
        block_rim: How far the block's drawn colour reaches beyond its outline (world units).
        frame_size: Side of the images it was perceived from (px).
        shape_cov: (4, 4) covariance of the outline's four lengths (`TeeShape.as_array`
            order, world units^2): the Laplace approximation of the fit plus a block
            jackknife over the outline's edges (`length_cov`); None where not known, and then
            no block pose carries the outline's uncertainty.
    """

    shape: TeeShape
    goal: np.ndarray
    goal_cov: np.ndarray
    block_rim: float
    frame_size: int = FRAME_SIZE
    shape_cov: np.ndarray | None = None

    def __post_init__(self) -> None:
        cov = self.shape_cov
        if cov is None:
            return
        arr = real_float64(cov)
        if arr is None or arr.shape != (4, 4) or not np.all(np.isfinite(arr)):
            raise InputError(
                "Scene.shape_cov must be a (4, 4) array of finite numbers (the covariance of "
                f"the outline's four lengths) or None, got {cov!r}."
            )
        object.__setattr__(self, "shape_cov", arr)


@dataclass(frozen=True)
class BlockEstimate:
    """The block's pose read off one image.

    Attributes:
        pose: (3,) ``(x, y, theta)``: world units, radians in ``(-pi, pi]``.
        cov: (3, 3) its covariance: the Laplace approximation of the template fit plus a
            block jackknife over the outline's edges, plus the scene's outline uncertainty
            (`Scene.shape_cov`) carried through the fit (`outline_cov`). The outline's
            error is shared by every frame of an episode; the status's checks read the
            frame's own part only.
        status: ``"ok"``; ``"not_visible"`` (too little of the block's colour in the image);
            ``"occluded"`` (too much of the fitted T under the pusher); ``"poor_fit"`` (the
            template does not explain the image, or the pose is too uncertain).
        visible: Fraction of the T's expected area that shows the block's colour.
        hidden: Fraction of the fitted T's area under the pusher.
        rms: The fit's mismatch: summed absolute difference of the fitted T's and the image's
            block fraction over the fitted T's area (0: a perfect fit).
        extra: The fit's details: ``rim`` (the block's rim it used) and ``cost``.
    """

    pose: np.ndarray
    cov: np.ndarray
    status: str
    visible: float
    hidden: float
    rms: float
    extra: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @property
    def ok(self) -> bool:
        """Whether the pose may be planned on."""
        return self.status == "ok"

    def std(self) -> np.ndarray:
        """(3,) standard deviations of ``x, y`` (world units) and ``theta`` (radians)."""
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0))


def _wrap(theta: float) -> float:
    return float(math.atan2(math.sin(theta), math.cos(theta)))


def _window(mask: np.ndarray, margin: int) -> tuple[slice, slice]:
    rows, cols = np.nonzero(mask)
    n = mask.shape[0]
    return (
        slice(max(int(rows.min()) - margin, 0), min(int(rows.max()) + margin + 1, n)),
        slice(max(int(cols.min()) - margin, 0), min(int(cols.max()) + margin + 1, n)),
    )


def _grid(size: int, window: tuple[slice, slice]) -> np.ndarray:
    rows, cols = np.mgrid[window[0], window[1]]
    return pixel_to_world(rows.ravel(), cols.ravel(), size)


def _start_poses(centroid: np.ndarray, local: np.ndarray, starts: int) -> list[np.ndarray]:
    """Poses whose T's centre of area lies on `centroid`, at `starts` angles."""
    out = []
    for theta in np.linspace(-math.pi, math.pi, starts, endpoint=False):
        co, si = math.cos(theta), math.sin(theta)
        offset = np.array([co * local[0] - si * local[1], si * local[0] + co * local[1]])
        out.append(np.array([*(centroid - offset), theta]))
    return out


def _frames(frames: Any) -> list[np.ndarray]:
    if isinstance(frames, np.ndarray):
        frames = [frames] if frames.ndim == 3 else list(frames)
    if isinstance(frames, (str, bytes)) or not isinstance(frames, Sequence) or not frames:
        raise InputError(
            "frames must be one (N, N, 3) uint8 image or a non-empty sequence of them (the first "
            "frames of an episode)."
        )
    out = [check_pixels(f, f"frames[{i}]") for i, f in enumerate(frames)]
    if len({f.shape for f in out}) != 1:
        raise InputError(f"frames must all have one size, got {sorted({f.shape for f in out})}.")
    return out


def _goal_evidence(
    fractions: Sequence[np.ndarray], opts: PerceptionOptions
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The goal region's colour over frames, each pixel where the block and pusher leave it.

    Args:
        fractions: (N, N, 4) class fractions of each frame.
        opts: Fit settings (`PerceptionOptions.unknown`).

    Returns:
        Every pixel's world point `(N * N, 2)`, the goal's mean fraction there `(N * N,)`, and
        a weight `(N * N,)`: 1 where some frame shows the pixel unoccluded, else 0.

    Raises:
        InputError: If the frames show no goal region.
    """
    size = fractions[0].shape[0]
    goal_sum = np.zeros((size, size))
    seen = np.zeros((size, size))
    for frac in fractions:
        clear = frac[..., 2] + frac[..., 3] <= opts.unknown
        goal_sum += np.where(clear, frac[..., 1], 0.0)
        seen += clear
    goal = np.where(seen > 0, goal_sum / np.maximum(seen, 1), 0.0)
    if goal.sum() < 4:
        raise InputError(
            "frames show no goal region (green T) to perceive; pass the episode's first frames."
        )
    rows, cols = np.mgrid[0:size, 0:size].reshape(2, -1)
    return pixel_to_world(rows, cols, size), goal.ravel(), (seen > 0).astype(float).ravel()


def _goal_residual(
    points: np.ndarray, observed: np.ndarray, weight: np.ndarray
) -> Callable[[np.ndarray, float], np.ndarray]:
    """The goal region's weighted residual of ``[pose (3), lengths (4)]`` and a ramp.

    Args:
        points: World points `(P, 2)`, as `_goal_evidence` returns them.
        observed: The goal's fraction there `(P,)`.
        weight: Their weights `(P,)`: 0 where no frame shows the pixel.
    """

    def res(p: np.ndarray, ramp: float) -> np.ndarray:
        return weight * (tee_fraction(p[:3], p[3:], _GOAL_RIM, points, ramp) - observed)

    return res


def perceive_scene(frames: Any, options: PerceptionOptions | None = None) -> Scene:
    """Perceive the T's outline, the goal region and the block's rim from frames of an episode.

    The goal region is the green T; where the block or the pusher hides it in one frame another
    frame may show it, so the goal's colour is averaged over the frames where each pixel is
    unoccluded. A T (pose and four lengths) is fitted to it, starting from a T of the goal
    region's size. The block's rim is then fitted, with the same outline, to the block in the
    first frame where it is seen well. Where more than `PerceptionOptions.goal_hidden` of the
    goal's T stays hidden, or the block fits no T of the goal's lengths, the lengths are
    fitted to the goal region and the block together (`_joint_fit`).

    Args:
        frames: One (N, N, 3) uint8 image or a sequence of them (e.g. an episode's first).
        options: Fit settings.

    Returns:
        The `Scene`.

    Raises:
        InputError: If the frames are malformed, or no frame shows the goal region or the block
            well enough to fit them.
    """
    opts = options or PerceptionOptions()
    images = _frames(frames)
    size = images[0].shape[0]
    fractions = [class_fractions(f) for f in images]
    points, observed, w = _goal_evidence(fractions, opts)
    area = float(observed.sum()) * (WORLD_SIZE / size) ** 2
    inside = observed > 0.5
    centroid = (points * observed[:, None]).sum(0) / observed.sum()
    extent = float(np.max(np.linalg.norm(points[inside] - centroid, axis=1))) * 2
    # a first T: bar and stem of one length L and one width t, as large as the region
    length = extent / math.sqrt(2)
    width = length - math.sqrt(max(length**2 - area, 0.0))
    dims0 = np.array([length, width, width, length - width])

    res = _goal_residual(points, observed, w)
    starts = _start_poses(centroid, TeeShape(*dims0).centroid(), opts.starts)
    scale = np.r_[1.0, 1.0, 0.02, 1.0, 1.0, 1.0, 1.0]
    best = fit_ramped(res, (np.r_[x, dims0] for x in starts), scale, opts.ramps, max_nfev=60)
    shape = TeeShape(*(float(v) for v in np.abs(best.x[3:])))
    goal_pose = np.array([best.x[0], best.x[1], _wrap(best.x[2])])
    goal_cov = laplace_cov(best, 7)[:3, :3]
    drawn = tee_fraction(best.x[:3], best.x[3:], _GOAL_RIM, points, opts.ramps[-1])
    hidden = float((drawn * (1.0 - w)).sum() / max(drawn.sum(), 1e-9))
    tried: list[tuple[np.ndarray, BlockEstimate]] = []
    for frac in fractions:
        est = _fit_block(frac, shape, None, opts, rim_free=True)
        if est is not None and est.status == "ok" and hidden <= opts.goal_hidden:
            groups = edge_groups(best.x[:3], shape, points)
            shape_cov = length_cov(lambda p: res(p, opts.smooth_ramp), best, groups, scale)
            return Scene(shape, goal_pose, goal_cov, float(est.extra["rim"]), size, shape_cov)
        if est is not None and np.all(np.isfinite(est.pose)):
            tried.append((frac, est))
    if tried:  # the goal alone does not pin the outline down: the block covers part of it
        frac, est = min(tried, key=lambda t: t[1].rms)
        joint = _joint_fit(res, points, best.x, [(frac, est)], opts)
        if joint is not None:
            return Scene(joint[0], joint[1], goal_cov, joint[2], size, joint[3])
    raise InputError(
        "no frame shows the block well enough to perceive its rim; pass more of the "
        "episode's frames."
    )


def _joint_fit(
    goal_residual: Callable[[np.ndarray, float], np.ndarray],
    goal_points: np.ndarray,
    goal_fit: np.ndarray,
    blocks: Sequence[tuple[np.ndarray, BlockEstimate]],
    opts: PerceptionOptions,
) -> tuple[TeeShape, np.ndarray, float, np.ndarray] | None:
    """The outline fitted to the goal region and the block in one or more frames at once.

    Where the block lies over the goal region at the reset, the region's visible part leaves
    the outline's lengths loose, and the block then fits no T of those lengths. And one
    image samples an edge only every 5.3 world units, so one region pins a length down only
    to a unit or two. The goal's pose, the block's pose in each frame, the four lengths and
    the block's rim are then fitted at once: every frame samples the one outline afresh.

    Args:
        goal_residual: The goal region's weighted residual of ``[pose, lengths]`` and a ramp.
        goal_points: (P, 2) the world points of that residual's pixels.
        goal_fit: (7,) the goal-only fit ``[x, y, theta, lengths]``.
        blocks: For each frame, its (N, N, 4) class fractions and its block fit (with the
            goal-only outline, or the last one; `extra["rim"]` the rim it used).
        opts: Fit settings.

    Returns:
        The outline, the goal's pose, the block's rim and the lengths' (4, 4) covariance
        (`length_cov`, each edge left out of the goal and every frame at once), if the
        block's fit with them is accepted (`_fit_block`'s checks) in every frame.
    """
    pixels = [_block_pixels(frac, opts) for frac, _ in blocks]
    k = len(blocks)

    def res(p: np.ndarray, ramp: float) -> np.ndarray:
        dims, rim = p[3:7], p[7]
        out = [goal_residual(np.r_[p[:3], dims], ramp)]
        for i, (points, observed, weight) in enumerate(pixels):
            drawn = tee_fraction(p[8 + 3 * i : 11 + 3 * i], dims, rim, points, ramp)
            out.append(weight * (drawn - observed))
        return np.concatenate(out)

    rim0 = float(np.mean([est.extra["rim"] for _, est in blocks]))
    x0 = np.concatenate([goal_fit[:3], goal_fit[3:], [rim0], *(est.pose for _, est in blocks)])
    scale = np.array([1.0, 1.0, 0.02, 1.0, 1.0, 1.0, 1.0, 0.5] + [1.0, 1.0, 0.02] * k)
    fit = fit_ramped(res, [x0], scale, opts.ramps, max_nfev=80)
    shape = TeeShape(*(float(v) for v in np.abs(fit.x[3:7])))
    rims = []
    for i, (frac, _) in enumerate(blocks):
        guess = fit.x[8 + 3 * i : 11 + 3 * i]
        check = _fit_block(frac, shape, None, opts, guess=guess, rim_free=True)
        if check is None or check.status != "ok":
            return None
        rims.append(float(check.extra["rim"]))
    groups = np.concatenate(
        [edge_groups(fit.x[:3], shape, goal_points)]
        + [
            edge_groups(fit.x[8 + 3 * i : 11 + 3 * i], shape, points)
            for i, (points, _, _) in enumerate(pixels)
        ]
    )
    shape_cov = length_cov(lambda p: res(p, opts.smooth_ramp), fit, groups, scale)
    goal = np.array([fit.x[0], fit.x[1], _wrap(fit.x[2])])
    return shape, goal, float(np.mean(rims)), shape_cov


def refine_scene(
    scene: Scene,
    goal_frames: Any,
    block_frames: Any,
    options: PerceptionOptions | None = None,
) -> Scene:
    """The scene perceived again from the goal region and the block in several frames.

    One frame samples the T's outline only every 5.3 world units, and the lengths fitted to
    it can be off by a unit or two, which moves the perceived block against the perceived
    goal. Each frame of the block at another pose samples the outline afresh: the outline, the
    goal and the block's rim are fitted to all of them at once (`_joint_fit`), starting from
    `scene`.

    Args:
        scene: The scene perceived from the first frames (`perceive_scene`).
        goal_frames: The frames it was perceived from (one (N, N, 3) uint8 image or several).
        block_frames: Frames of the block at other poses (one image or several), e.g. after
            the first pushes.
        options: Fit settings.

    Returns:
        The refined `Scene`; `scene` itself where the block is not read well in every frame
        of `block_frames`, or the refined outline fits one of them poorly.

    Raises:
        InputError: If the frames are malformed, of another size than the scene's, or show
            no goal region.
    """
    opts = options or PerceptionOptions()
    goal_images, block_images = _frames(goal_frames), _frames(block_frames)
    for name, images in (("goal_frames", goal_images), ("block_frames", block_images)):
        if images[0].shape[0] != scene.frame_size:
            raise InputError(
                f"{name} must be {scene.frame_size} x {scene.frame_size} like the scene's "
                f"frames, got {images[0].shape[0]} x {images[0].shape[1]}."
            )
    evidence = _goal_evidence([class_fractions(f) for f in goal_images], opts)
    goal_res = _goal_residual(*evidence)
    blocks = []
    for image in block_images:
        frac = class_fractions(image)
        est = _fit_block(frac, scene.shape, scene.block_rim, opts)
        if est is None or not est.ok:
            return scene
        blocks.append((frac, est))
    start = np.r_[scene.goal, scene.shape.as_array()]
    joint = _joint_fit(goal_res, evidence[0], start, blocks, opts)
    if joint is None:
        return scene
    return Scene(joint[0], joint[1], scene.goal_cov, joint[2], scene.frame_size, joint[3])


def perceive_block(
    pixels: np.ndarray,
    scene: Scene,
    options: PerceptionOptions | None = None,
    guess: np.ndarray | None = None,
) -> BlockEstimate:
    """The block's pose in one image, with its uncertainty and whether it may be used.

    Args:
        pixels: (N, N, 3) uint8 RGB image, N the scene's frame size.
        scene: The perceived scene (`perceive_scene`): the T's outline and the block's rim.
        options: Fit settings and the checks' thresholds.
        guess: (3,) a pose to start from (e.g. the last one); None, or a start that ends in a
            frame not accepted, searches over `PerceptionOptions.starts` angles.

    Returns:
        The `BlockEstimate`; a frame that does not show the block well enough has a status
        other than ``"ok"`` (its pose is then the best fit found, or NaN if none).

    Raises:
        InputError: If `pixels` is malformed or not of the scene's size.
    """
    opts = options or PerceptionOptions()
    img = check_pixels(pixels)
    if img.shape[0] != scene.frame_size:
        raise InputError(
            f"pixels must be {scene.frame_size} x {scene.frame_size} like the frames the scene "
            f"was perceived from, got {img.shape[0]} x {img.shape[1]}."
        )
    frac = class_fractions(img)
    outline = scene.shape_cov
    est = _fit_block(frac, scene.shape, scene.block_rim, opts, guess=guess, shape_cov=outline)
    if guess is not None and est is not None and not est.ok:  # lost track: search again
        est = _fit_block(frac, scene.shape, scene.block_rim, opts, shape_cov=outline)
    if est is None:
        nan = np.full(3, np.nan)
        return BlockEstimate(nan, np.full((3, 3), np.nan), "not_visible", 0.0, 0.0, math.nan)
    return est


def _block_pixels(
    frac: np.ndarray, opts: PerceptionOptions
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels a block fit reads: around the block's colour and the pusher's.

    Returns:
        Their world points `(P, 2)`, the block's fraction there `(P,)`, and a weight `(P,)`
        that leaves out the pixels the pusher covers.
    """
    block, agent = frac[..., 2], frac[..., 3]
    window = _window((block > 0.05) | (agent > opts.unknown), opts.margin)
    observed = block[window].ravel()
    weight = (agent[window].ravel() <= opts.unknown).astype(float)
    return _grid(frac.shape[0], window), observed, weight


def _fit_block(
    frac: np.ndarray,
    shape: TeeShape,
    rim: float | None,
    opts: PerceptionOptions,
    *,
    guess: np.ndarray | None = None,
    rim_free: bool = False,
    shape_cov: np.ndarray | None = None,
) -> BlockEstimate | None:
    """Fit the T to the block's colour fraction `frac[..., 2]`; None if it shows nowhere.

    With `shape_cov` (the outline's (4, 4) covariance) the pose's covariance also carries
    the outline's uncertainty (`outline_cov`); the status reads the frame's own part.
    """
    size = frac.shape[0]
    block = frac[..., 2]
    pixel_area = (WORLD_SIZE / size) ** 2
    rim0 = 2.5 if rim is None else rim
    expected = shape.area() + rim0 * 2 * (shape.bar_length + shape.bar_width + shape.stem_length)
    visible = float(block.sum()) * pixel_area / expected
    if block.sum() < 1.0:
        return None
    points, observed, weight = _block_pixels(frac, opts)
    dims = shape.as_array()
    n = 4 if rim_free else 3
    scale = np.r_[1.0, 1.0, 0.02, 0.5][:n]

    def model(p: np.ndarray, ramp: float) -> np.ndarray:
        r = p[3] if rim_free else rim0
        return tee_fraction(p[:3], dims, r, points, ramp)

    if guess is not None:
        starts = [np.asarray(guess, dtype=float)[:3]]
    else:
        centroid = (points * observed[:, None]).sum(0) / max(observed.sum(), 1e-9)
        starts = _start_poses(centroid, shape.centroid(), opts.starts)

    def res(p: np.ndarray, ramp: float) -> np.ndarray:
        return weight * (model(p, ramp) - observed)

    best = fit_ramped(res, (np.r_[x, rim0][:n] for x in starts), scale, opts.ramps, max_nfev=20)
    predicted = model(best.x, opts.ramps[-1])
    hidden = float((predicted * (1.0 - weight)).sum() / max(predicted.sum(), 1e-9))
    seen = weight > 0
    rms = float(np.abs(predicted - observed)[seen].sum() / max(predicted[seen].sum(), 1e-9))
    groups = edge_groups(best.x[:3], shape, points)
    subsets = []
    for g in range(groups.max() + 1):
        keep = weight * (groups != g)

        def res_g(p: np.ndarray, keep: np.ndarray = keep) -> np.ndarray:
            return keep * (model(p, opts.ramps[-1]) - observed)

        subsets.append(fit_least_squares(res_g, best.x, scale, max_nfev=12).x[:3])
    sub = np.asarray(subsets)
    sub[:, 2] = best.x[2] + np.array([_wrap(t - best.x[2]) for t in sub[:, 2]])
    dev = sub - sub.mean(0)
    # a point-sampled edge lies within one sample spacing: at most that uniform uncertainty
    spacing = WORLD_SIZE / size
    quantised = np.array([12.0, 12.0]) / spacing**2
    cov = laplace_cov(best, n, quantised)[:3, :3] + (len(sub) - 1) / len(sub) * dev.T @ dev
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    px = size / WORLD_SIZE
    if hidden > opts.max_hidden:
        status = "occluded"
    elif visible < opts.min_visible:
        status = "not_visible"
    elif (
        rms > opts.max_rms
        or not np.all(np.isfinite(std))
        or max(std[0], std[1]) * px > opts.max_std_px
        or math.degrees(std[2]) > opts.max_std_deg
    ):
        status = "poor_fit"
    else:
        status = "ok"
    if shape_cov is not None:
        r = best.x[3] if rim_free else rim0
        cov = cov + outline_cov(
            lambda p, d: tee_fraction(p, d, r, points, opts.smooth_ramp),
            best.x[:3],
            dims,
            weight,
            shape_cov,
        )
    pose = np.array([best.x[0], best.x[1], _wrap(best.x[2])])
    extra = {
        "rim": float(best.x[3]) if rim_free else rim0,
        "cost": best.cost,
    }
    return BlockEstimate(pose, cov, status, visible, hidden, rms, extra)
