"""Pushability of warehouse boxes from perception: a per-direction voxel classifier and its test.

`AffordanceClassifier` holds one standardised logistic regression per direction (up, down,
left, right), trained on voxel features (`probaff.features.cells`) labelled with the
ground-truth rule (`rule_affordances`) of each voxel's cell. A cell's prediction averages the
probabilities of its voxels.

`evaluate` measures it as in chapter 3: it generates maps, explores each from a random free
cell, computes the features, and cross-validates over the described cells (cells with at least
one voxel): stratified K-fold over cells and, optionally, K-fold grouped by map (no map in both
the training and the test folds). A cell counts as pushable in a direction when its averaged
probability is at least 0.5. Precision and recall pool the out-of-fold predictions of all folds.

Covered by tests/planning/manipulation/test_affordance_classifier.py.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from sklearn.metrics import precision_score, recall_score
from sklearn.model_selection import GroupKFold, StratifiedKFold

from probaff._checks import (
    as_bool_array,
    as_float_array,
    check_count,
    check_finite,
    check_positive,
    check_shape,
)
from probaff.errors import InputError
from probaff.features.cells import cell_features
from probaff.grid import DIRECTION_NAMES
from probaff.perception.exploration import explore, grid_distances
from probaff.perception.labels import PerColumnLogistic
from probaff.perception.occupancy import FREE_SPACE
from probaff.sim.warehouse import generate_map, rule_affordances
from probaff.sim.warehouse_config import WarehouseSpec, load_warehouse

__all__ = [
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "VoxelDataset",
    "collect_voxels",
    "evaluate",
]


class AffordanceClassifier(PerColumnLogistic):
    """One standardised logistic regression per push direction, over voxel features.

    Args:
        C: Inverse L2 regularisation strength of each logistic regression.
        max_iter: Iteration limit of the solver (a positive integer).

    Raises:
        InputError: If `C` is not a finite number > 0 or `max_iter` is not a positive
            integer.
    """

    C_NAME = "C (inverse regularisation strength)"

    def fit(self, features: np.ndarray, labels: np.ndarray) -> AffordanceClassifier:
        """Train on labelled voxels.

        A direction whose training labels are all equal predicts that constant.

        Args:
            features: (N, D) voxel features.
            labels: (N, 4) bool, pushability of each voxel's cell per direction.

        Returns:
            ``self``.

        Raises:
            InputError: For mismatched shapes, no samples, or non-finite features.
        """
        x = self._check_features(features, fitting=True)
        check_shape("labels", labels, (x.shape[0], len(DIRECTION_NAMES)))
        self._fit_columns(x, as_bool_array("labels", labels))
        return self

    def _check_features(self, features: np.ndarray, fitting: bool = False) -> np.ndarray:
        x = as_float_array("features", features)
        check_shape("features", x, (None, None if fitting else self._width))
        check_finite("features", x)
        if fitting:
            if not len(x):
                raise InputError("features hold no voxels; fit needs at least one.")
            self._width = x.shape[1]
        return x

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        """Per-voxel pushability probabilities.

        Args:
            features: (N, D) voxel features, D as in training.

        Returns:
            (N, 4) probability of each direction (up, down, left, right).

        Raises:
            InputError: Before `fit`, or for features of the wrong width or non-finite.
        """
        if self._models is None:
            raise InputError("the classifier is not trained; call fit(features, labels) first.")
        return self._predict_columns(self._check_features(features))

    def predict_cells(
        self, features: np.ndarray, cells: np.ndarray, map_shape: tuple[int, int]
    ) -> np.ndarray:
        """Per-cell pushability probabilities: the mean over each cell's voxels.

        Args:
            features: (N, D) voxel features.
            cells: (N, 2) int, ``(row, col)`` of each voxel's cell.
            map_shape: ``(rows, cols)`` of the map.

        Returns:
            (rows, cols, 4) probabilities; NaN in cells without voxels (free or unseen).

        Raises:
            InputError: Before `fit`, for mismatched shapes, or cells outside the map.
        """
        p = self.predict_proba(features)
        check_shape("cells", cells, (len(p), 2))
        if not isinstance(map_shape, (tuple, list)) or len(map_shape) != 2:
            raise InputError(f"map_shape must be (rows, cols), got {map_shape!r}.")
        rows, cols = (
            check_count(f"map_shape {k}", v)
            for k, v in zip(("rows", "cols"), map_shape, strict=True)
        )
        c = np.asarray(cells)
        if len(c) and (c.min() < 0 or c[:, 0].max() >= rows or c[:, 1].max() >= cols):
            raise InputError(f"cells must lie inside the {rows} x {cols} map.")
        flat = c[:, 0] * cols + c[:, 1] if len(c) else np.empty(0, dtype=np.int64)
        return _cell_means(p, flat, rows * cols).reshape(rows, cols, -1)


def _cell_means(values: np.ndarray, cell: np.ndarray, n_cells: int) -> np.ndarray:
    """(n_cells, K) mean of the (N, K) `values` per cell id in ``range(n_cells)``; NaN if none."""
    n = np.bincount(cell, minlength=n_cells).astype(float)
    sums = np.stack([np.bincount(cell, values[:, k], n_cells) for k in range(values.shape[1])], -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / n[:, None]


@dataclass(frozen=True)
class VoxelDataset:
    """Labelled voxels of explored maps.

    Attributes:
        features: (N, D) voxel features.
        names: (D,) feature column names.
        labels: (N, 4) bool, the rule's pushability of each voxel's cell.
        cell_ids: (N,) int, a cell id unique over all maps, ``map * rows * cols + row * cols +
            col``.
        map_ids: (N,) int, the map of each voxel.
        coverage: (n_maps,) share of the cells reachable from each start that exploration
            knows to be free.
        unseen_boxes: Boxes without any described voxel, over all maps.
        n_boxes: Boxes over all maps.
        scans: Scans taken over all maps.
    """

    features: np.ndarray
    names: tuple[str, ...]
    labels: np.ndarray
    cell_ids: np.ndarray
    map_ids: np.ndarray
    coverage: np.ndarray
    unseen_boxes: int
    n_boxes: int
    scans: int


@dataclass(frozen=True)
class AffordanceEvaluation:
    """Cross-validated precision and recall of cell-level pushability, per direction.

    Attributes:
        precision: (4,) stratified K-fold over cells, (up, down, left, right).
        recall: (4,) likewise.
        grouped_precision: (4,) K-fold grouped by map, or None if not run.
        grouped_recall: (4,) likewise.
        n_maps: Maps explored.
        n_cells: Cells described (with at least one voxel).
        n_voxels: Voxels described.
        positives: (4,) cells pushable per direction.
        coverage: Mean share of reachable cells that exploration knows to be free.
        unseen_boxes: Boxes without any described voxel.
        n_boxes: Boxes over all maps.
        scans: Scans taken over all maps.
        seconds: Wall-clock time of the whole evaluation.
    """

    precision: np.ndarray
    recall: np.ndarray
    grouped_precision: np.ndarray | None
    grouped_recall: np.ndarray | None
    n_maps: int
    n_cells: int
    n_voxels: int
    positives: np.ndarray
    coverage: float
    unseen_boxes: int
    n_boxes: int
    scans: int
    seconds: float

    def table(self) -> str:
        """A plain-text table of precision and recall (%) per direction."""
        head = f"{'direction':<10}{'precision':>10}{'recall':>8}"
        grouped = self.grouped_precision is not None and self.grouped_recall is not None
        if grouped:
            head += f"{'grp prec':>10}{'grp rec':>9}"
        lines = [head]
        for k, name in enumerate(DIRECTION_NAMES):
            line = f"{name:<10}{100 * self.precision[k]:>10.1f}{100 * self.recall[k]:>8.1f}"
            if self.grouped_precision is not None and self.grouped_recall is not None:
                line += (
                    f"{100 * self.grouped_precision[k]:>10.1f}{100 * self.grouped_recall[k]:>9.1f}"
                )
            lines.append(line)
        return "\n".join(lines)


def collect_voxels(spec: WarehouseSpec, n_maps: int, rng: np.random.Generator) -> VoxelDataset:
    """Generate maps, explore each from a random free cell, and label the voxel features.

    Args:
        spec: The warehouse world.
        n_maps: How many maps (a positive integer).
        rng: Source of the maps, the starts and the sensor noise.

    Returns:
        The labelled voxels of all maps.

    Raises:
        InputError: If `spec` is not a `WarehouseSpec`, `n_maps` is not a positive integer or
            `rng` is not a ``numpy.random.Generator``.
    """
    if not isinstance(spec, WarehouseSpec):
        raise InputError(
            f"spec must be the warehouse world, a WarehouseSpec (load_warehouse()), got "
            f"{type(spec).__name__}."
        )
    n_maps = check_count("n_maps", n_maps)
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}."
        )
    n_cells = spec.rows * spec.cols
    feats, labels, cell_ids, map_ids, coverage = [], [], [], [], []
    unseen = boxes = scans = 0
    names: tuple[str, ...] = ()
    for i in range(n_maps):
        m = generate_map(spec, rng)
        free = np.argwhere(~m.occupancy)
        start = free[rng.integers(len(free))]
        run = explore(spec, m, start, rng)
        vox = cell_features(run.points, run.grid)
        names = vox.features.names
        truth = rule_affordances(m)
        flat = vox.cells[:, 0] * spec.cols + vox.cells[:, 1]
        feats.append(vox.features.values)
        labels.append(truth[vox.cells[:, 0], vox.cells[:, 1]])
        cell_ids.append(i * n_cells + flat)
        map_ids.append(np.full(len(flat), i))
        reach = grid_distances(~m.occupancy, (int(start[0]), int(start[1]))) >= 0
        coverage.append(float((run.grid.cell_states()[reach] == FREE_SPACE).mean()))
        described = np.zeros(n_cells, dtype=bool)
        described[flat] = True
        boxes += int(m.occupancy.sum())
        unseen += int((m.occupancy.ravel() & ~described).sum())
        scans += len(run.cells)
    return VoxelDataset(
        features=np.concatenate(feats),
        names=names,
        labels=np.concatenate(labels),
        cell_ids=np.concatenate(cell_ids),
        map_ids=np.concatenate(map_ids),
        coverage=np.array(coverage),
        unseen_boxes=unseen,
        n_boxes=boxes,
        scans=scans,
    )


def _out_of_fold(
    data: VoxelDataset,
    splits: list[tuple[np.ndarray, np.ndarray]],
    cell_index: np.ndarray,
    n_cells: int,
    C: float,
) -> np.ndarray:
    """(n_cells, 4) out-of-fold cell probabilities for the given cell-level splits."""
    prob = np.full((n_cells, len(DIRECTION_NAMES)), np.nan)
    for train, test in splits:
        train_vox = np.isin(cell_index, train)
        test_vox = np.isin(cell_index, test)
        model = AffordanceClassifier(C=C).fit(data.features[train_vox], data.labels[train_vox])
        p = model.predict_proba(data.features[test_vox])
        means = _cell_means(p, cell_index[test_vox], n_cells)
        prob[test] = means[test]
    return prob


def _strata(ways: np.ndarray, folds: int) -> np.ndarray:
    """Stratum of each cell: how many ways its box can move, rare counts pooled.

    Counts held by fewer than `folds` cells join the nearest well-populated count, so that every
    stratum can appear in every fold.

    Args:
        ways: (n,) int, pushable directions per cell.
        folds: Number of folds.

    Returns:
        (n,) int stratum labels.
    """
    values, counts = np.unique(ways, return_counts=True)
    common = values[counts >= folds]
    if not len(common):
        return np.zeros_like(ways)
    nearest = np.abs(ways[:, None] - common[None, :]).argmin(1)
    return common[nearest]


def _scores(prob: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pred = prob >= 0.5
    precision = np.array(
        [precision_score(truth[:, k], pred[:, k], zero_division=0.0) for k in range(truth.shape[1])]
    )
    recall = np.array(
        [recall_score(truth[:, k], pred[:, k], zero_division=0.0) for k in range(truth.shape[1])]
    )
    return precision, recall


def evaluate(
    n_maps: int = 20,
    folds: int = 10,
    seed: int = 0,
    grouped: bool = True,
    C: float = 1.0,
    spec: WarehouseSpec | None = None,
) -> AffordanceEvaluation:
    """Cross-validate the classifier on freshly generated and explored maps.

    Args:
        n_maps: Maps to generate and explore (a positive integer).
        folds: Folds of each cross-validation (an integer >= 2).
        seed: Seed of the maps, starts, sensor noise and fold assignment (an integer >= 0).
        grouped: Also run K-fold grouped by map (``min(folds, n_maps)`` folds).
        C: Inverse regularisation strength of the logistic regressions.
        spec: The warehouse world; default `load_warehouse()`.

    Returns:
        Precision and recall per direction, with dataset statistics.

    Raises:
        InputError: For a non-integer or negative count or seed, fewer than 2 folds, a `C`
            that is not > 0, or too few described cells for them.
    """
    t0 = time.perf_counter()
    n_maps = check_count("n_maps", n_maps)
    folds = check_count("folds", folds, minimum=2)
    seed = check_count("seed", seed, minimum=0)
    check_positive("C (inverse regularisation strength)", C)
    spec = spec or load_warehouse()
    data = collect_voxels(spec, n_maps, np.random.default_rng(seed))
    cells, cell_index = np.unique(data.cell_ids, return_inverse=True)
    n_cells = len(cells)
    if n_cells < folds:
        raise InputError(f"only {n_cells} cells were described; use more maps or fewer folds.")
    first = np.zeros(n_cells, dtype=np.int64)
    first[cell_index] = np.arange(len(cell_index))
    truth = data.labels[first]
    map_of_cell = data.map_ids[first]
    strata = _strata(truth.sum(1), folds)
    kfold = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
    splits = list(kfold.split(np.zeros(n_cells), strata))
    precision, recall = _scores(_out_of_fold(data, splits, cell_index, n_cells, C), truth)
    g_precision = g_recall = None
    n_groups = len(np.unique(map_of_cell))
    if grouped and n_groups >= 2:
        gkf = GroupKFold(n_splits=min(folds, n_groups))
        g_splits = list(gkf.split(np.zeros(n_cells), groups=map_of_cell))
        g_precision, g_recall = _scores(_out_of_fold(data, g_splits, cell_index, n_cells, C), truth)
    return AffordanceEvaluation(
        precision=precision,
        recall=recall,
        grouped_precision=g_precision,
        grouped_recall=g_recall,
        n_maps=n_maps,
        n_cells=n_cells,
        n_voxels=len(data.features),
        positives=truth.sum(0),
        coverage=float(data.coverage.mean()),
        unseen_boxes=data.unseen_boxes,
        n_boxes=data.n_boxes,
        scans=data.scans,
        seconds=time.perf_counter() - t0,
    )
