"""Settings of the chapter 2 study: its config, the thesis's data set and the smoke sizes."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.experiments.base import StudyConfig
from probaff.perception.label_boosting import THRESHOLD_RULES, BoostingOptions
from probaff.perception.merge import PROXIMITIES
from probaff.perception.scan_labels import PerceptionConfig

__all__ = ["SMOKE", "THESIS_SEGMENTS", "PointCloudStudyConfig"]

THESIS_SEGMENTS = (195, 10)
"""The thesis's data set: 195 segments from 10 office scenes."""

SMOKE: Mapping[str, Any] = MappingProxyType(
    {
        "n_scenes": 4,
        "scene_counts": (4,),
        "n_splits": 2,
        "perception": PerceptionConfig(pans_deg=(0.0,)),
        "min_gains": (0.1,),
        "view_counts": (1, 2),
        "merge_pans_deg": (-10.0, 10.0),
        "merge_scenes": 1,
        "boosting_rounds": 10,
        "progress": False,
    }
)
"""Sizes of a tiny run that checks the whole pipeline in seconds."""


@dataclass(frozen=True, kw_only=True)
class PointCloudStudyConfig(StudyConfig):
    """Settings of the chapter 2 study.

    Attributes:
        out: Output folder (per-scene records, tables, figures).
        seed: Seed of the scenes, the scans, the CV folds and the 2-means runs.
        n_scenes: Scenes of the headline CV, Algorithm 1 and the merge classifiers (the
            thesis's 10).
        scene_counts: Scene counts of the label CV (the first n scenes each); larger ones show
            how the classifiers improve with data.
        n_splits: Folds of the CV by scene (the thesis's 4).
        label_min_points: Further label CVs, each on the segments of at least this many
            points only (the same scenes and folds). Region growing keeps segments from
            ``perception.min_size`` (50) points, about 66 a scene; at 300 points about 24 a
            scene are left, near the thesis's 19.5.
        perception: The scan-to-segments pipeline's settings.
        min_gains: Algorithm 1's entropy drop below which a split is undone (nats; 0 is the
            thesis's rule).
        view_counts: Views merged in the merge study (each at most the merge views).
        merge_pans_deg: Pan angles of the merge scans (degrees, left positive), centre out.
        merge_scenes: How many of the first scenes the merge study scans again.
        merge_proximities: How the merge reads "segments lie close", each of `PROXIMITIES`
            (``"points"``: nearest points; ``"centroid"``: centroids); the first one is drawn
            in the figure.
        boosting_rounds: Boosting rounds of each label's trees in the model comparison
            (`BoostingOptions.max_iter`).
        boosting_threshold: How the trees of the model comparison choose each label's
            decision threshold (`BoostingOptions.threshold`): ``"balanced"`` (the smaller of
            precision and recall of an inner CV by scene on the training scenes, largest),
            ``"f1"``, ``"fixed"`` (0.5, the study's numbers before the thresholds) or a
            number in (0, 1) written as text (``"0.6"``).
        boosting_calibration: How the trees of the model comparison calibrate their scores
            (`BoostingOptions.calibration`): ``"sigmoid"`` (Platt scaling, the default) or
            ``"isotonic"`` (the study's numbers before it).
    """

    out: str = "results/point_cloud_labels"
    n_scenes: int = 10
    scene_counts: tuple[int, ...] = (10, 30)
    n_splits: int = 4
    label_min_points: tuple[int, ...] = (300,)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    min_gains: tuple[float, ...] = (0.0, 0.05, 0.1, 0.2)
    view_counts: tuple[int, ...] = (1, 2, 4)
    merge_pans_deg: tuple[float, ...] = (-10.0, 10.0, -30.0, 30.0)
    merge_scenes: int = 10
    merge_proximities: tuple[str, ...] = PROXIMITIES
    boosting_rounds: int = 200
    boosting_threshold: str = "balanced"
    boosting_calibration: str = "sigmoid"

    SMOKE: ClassVar[Mapping[str, Any]] = SMOKE

    def check(self) -> dict[str, Any]:
        """Raise `InputError` for impossible counts, gains, views or settings."""
        check_count("n_scenes", self.n_scenes, minimum=2)
        splits = check_count("n_splits", self.n_splits, minimum=2)
        if not self.scene_counts:
            raise InputError("scene_counts is empty; give at least one scene count, e.g. 10.")
        for n in self.scene_counts:
            if check_count("scene_counts", n) < splits:
                raise InputError(
                    f"scene_counts holds {n}, fewer scenes than n_splits={splits}; every CV "
                    "needs at least one scene per fold."
                )
        if self.n_scenes < splits:
            raise InputError(
                f"n_scenes={self.n_scenes} is fewer than n_splits={splits}; raise n_scenes."
            )
        for m in self.label_min_points:
            check_count("label_min_points", m)
        if not self.min_gains or any(
            not isinstance(g, (int, float)) or not math.isfinite(g) or g < 0 for g in self.min_gains
        ):
            raise InputError(
                f"min_gains must be finite numbers >= 0 (nats), got {self.min_gains!r}."
            )
        if not isinstance(self.perception, PerceptionConfig):
            raise InputError(
                f"perception must be a PerceptionConfig, got {type(self.perception).__name__}."
            )
        pans = self.merge_pans_deg
        if not pans or any(not isinstance(p, (int, float)) or not math.isfinite(p) for p in pans):
            raise InputError(f"merge_pans_deg must be finite angles (degrees), got {pans!r}.")
        if not self.view_counts:
            raise InputError("view_counts is empty; give at least one number of views, e.g. 1.")
        for v in self.view_counts:
            if check_count("view_counts", v) > len(pans):
                raise InputError(
                    f"view_counts holds {v}, more than the {len(pans)} merge_pans_deg; add "
                    "pans or lower the view count."
                )
        merged = check_count("merge_scenes", self.merge_scenes)
        if merged > self.n_scenes:
            raise InputError(
                f"merge_scenes={merged} exceeds n_scenes={self.n_scenes}; the merge scenes "
                "are among the first n_scenes."
            )
        self.boosting  # noqa: B018 -- raises for bad boosting_* settings
        proximities = self.merge_proximities
        if (
            not proximities
            or any(p not in PROXIMITIES for p in proximities)
            or len(set(proximities)) < len(proximities)
        ):
            raise InputError(
                f"merge_proximities must hold distinct names among {', '.join(PROXIMITIES)}, "
                f"got {proximities!r}."
            )
        return {}

    @property
    def boosting(self) -> BoostingOptions:
        """The model comparison's tree settings: the ``boosting_*`` fields and `seed`.

        ``boosting_threshold`` is text: a rule of `THRESHOLD_RULES`, or a number in (0, 1).

        Raises:
            InputError: Naming the ``boosting_*`` field out of range.
        """
        check_count("boosting_rounds", self.boosting_rounds)
        text = self.boosting_threshold
        threshold: str | float = text
        if isinstance(text, str) and text not in THRESHOLD_RULES:
            try:
                threshold = float(text)
            except ValueError:
                threshold = text
        try:
            return BoostingOptions(
                max_iter=self.boosting_rounds,
                seed=self.seed,
                threshold=threshold,
                calibration=self.boosting_calibration,
            )
        except InputError as err:
            message = re.sub(r"\b(threshold|calibration)\b", r"boosting_\1", str(err))
            raise InputError(message) from None

    @property
    def scanned(self) -> int:
        """Scenes scanned: the largest of `n_scenes` and `scene_counts`."""
        return max(self.n_scenes, *self.scene_counts)
