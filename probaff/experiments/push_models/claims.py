"""Chapter 5's claims judged with intervals over splits: holds, refuted, or not shown.

Each claim compares two cells of the study, (features, method, M) against another, split by
split on the same held-out pushes, so the comparison is paired. A split is one fold of one
repeat of the cross-validation (``ch5_repeats`` repeats of ``ch5_folds`` folds). An RMSE
comparison is the relative change ``RMSE(a) / RMSE(b) - 1`` in %, averaged over the claim's
effect dimensions (so metres and radians weigh alike); an NLPD comparison is the difference of
the total NLPD (nats per held-out push, summed over the six effects). The mean over the J
splits gets a 95 % interval, Nadeau and Bengio's corrected resampled t
(`probaff.eval.metrics.corrected_halfwidth`, variance ``sd^2 (1 / J + 1 / (K - 1))`` for K
folds): the splits share training rows, and the plain t interval over them is too narrow. The
verdict reads the interval against the thesis's direction:

* ``holds``: the whole interval lies on the thesis's side of 0;
* ``refuted``: the whole interval lies on the other side;
* ``below the thesis's size``: the interval holds 0 but none of the thesis's published effect
  (a number, or a range), so the effect the thesis reports is ruled out while no effect is
  not: the claim as published is refuted, its direction neither shown nor refuted;
* ``not shown``: the interval holds 0 (and, where the thesis gives a number, that number too);
* ``too few folds``: fewer than two splits, so no interval.

Beside the verdict, ``won`` (`repeats_won`) is the share of the repeats whose own mean lies on
the thesis's side of 0: how often one cross-validation, run once as the thesis ran it, would
have shown the claim's direction. It is not a test (the repeats share their pushes); it reads
how a single published run of a claim that an interval leaves open could come out.

The claims (thesis section 5.4): context features help o2 (f_o & f_c & f_x against f_o, o2's
three effects, -11.8 %); M > 1 beats M = 1 on RMSE (-5.9 to -6.5 %); M = 3 is best (the thesis's
"best average prediction": its RMSE, the relative change averaged over the six effects, below
every other M's; and, as a probabilistic model, its NLPD below every other M's); the
gate-on-context split (``gx-eoc``) is best for o1 along the push
(its o1 dz RMSE below all features' and f_o & f_c's, at every M > 1: with one expert there
is no gate, and ``gx-eoc`` is ``oc``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from probaff.errors import InputError
from probaff.eval.metrics import corrected_halfwidth
from probaff.eval.tables import markdown_table
from probaff.experiments.push_models.config import CH5_EFFECTS

__all__ = [
    "CLAIM_COLUMNS",
    "VERDICTS",
    "chapter5_claims",
    "claim_lines",
    "repeats_won",
    "split_halfwidth",
    "study_folds",
    "verdict",
]

CLAIM_COLUMNS = [
    "claim",
    "a",
    "b",
    "metric",
    "thesis",
    "repeats",
    "folds",
    "mean",
    "ci95",
    "verdict",
    "won",
]
"""Columns of the claims table (``ch5_claims.csv``): ``repeats`` of ``folds`` folds each;
``won`` is `repeats_won`'s share."""

VERDICTS = ("holds", "refuted", "below the thesis's size", "not shown", "too few folds")
"""What a comparison can find: see the module docstring; fewer than two folds give no
interval."""

_THESIS_SIZES = {"-11.8 %": (-11.8, -11.8), "-4.37 %": (-4.37, -4.37)}
_THESIS_SIZES["-5.9 to -6.5 %"] = (-6.5, -5.9)
"""The published effects (low, high) of the claims that give a number (section 5.4)."""

_O1_DZ = ("o1.dz",)
_O2 = CH5_EFFECTS[3:]


def verdict(
    mean: float,
    halfwidth: float,
    direction: int,
    folds: int,
    thesis: tuple[float, float] | None = None,
) -> str:
    """One of `VERDICTS` for an interval over folds and the thesis's sign (and size).

    Args:
        mean: Mean paired difference over folds.
        halfwidth: Half-width of its 95 % interval.
        direction: The thesis's sign of the difference, -1 or +1.
        folds: Splits the interval is over (repeats times folds).
        thesis: The thesis's published difference as ``(low, high)`` in the units of
            `mean`, or None where it gives no number.
    """
    if folds < 2:
        return "too few folds"
    lo, hi = direction * mean - halfwidth, direction * mean + halfwidth
    if lo > 0:
        return "holds"
    if hi < 0:
        return "refuted"
    if thesis is not None and (mean - halfwidth > thesis[1] or mean + halfwidth < thesis[0]):
        return "below the thesis's size"
    return "not shown"


Split = tuple[int, int]
"""A split of the cross-validation: (repeat, fold)."""


def split_halfwidth(values: Sequence[float], folds: int) -> float:
    """95 % half-width of the mean of one paired score per split (corrected resampled t).

    Args:
        values: One value per split (repeat, fold), `(J,)`.
        folds: Folds K of each repeat of the cross-validation: a split holds out 1 / K of
            the rows and trains on the rest, so ``n_test / n_train = 1 / (K - 1)``.
    """
    return corrected_halfwidth(values, 1 / (folds - 1) if folds > 1 else 0.0)


def repeats_won(values: Sequence[float], repeats: Sequence[int], direction: int) -> float:
    """Share of the repeats whose mean paired difference has the thesis's sign.

    Args:
        values: One paired difference per split, `(J,)`.
        repeats: The repeat of each split, `(J,)`.
        direction: The thesis's sign of the difference, -1 or +1.

    Returns:
        The share in [0, 1] of the distinct repeats whose mean over their folds is on the
        thesis's side of 0 (a tie at 0 counts against); NaN without splits.

    Raises:
        InputError: If `values` and `repeats` differ in length or `direction` is not +-1.
    """
    if len(values) != len(repeats):
        raise InputError(
            f"repeats_won: values and repeats must have one entry per split, got {len(values)} "
            f"and {len(repeats)}."
        )
    if direction not in (-1, 1):
        raise InputError(f"repeats_won: direction must be -1 or +1, got {direction!r}.")
    by_repeat: dict[int, list[float]] = {}
    for v, r in zip(values, repeats, strict=True):
        by_repeat.setdefault(int(r), []).append(float(v))
    if not by_repeat:
        return math.nan
    return float(np.mean([direction * np.mean(v) > 0 for v in by_repeat.values()]))


def study_folds(results: Sequence[dict[str, Any]]) -> int:
    """Folds of each repeat of the cross-validation the split rows `results` come from."""
    return 1 + max((int(r["fold"]) for r in results), default=0)


def _by_split(
    results: list[dict[str, Any]], method: str
) -> dict[tuple[str, int], dict[Split, dict[str, Any]]]:
    """Split rows of `method`, by (features, M) and then (repeat, fold)."""
    out: dict[tuple[str, int], dict[Split, dict[str, Any]]] = {}
    for r in results:
        if r["method"] == method:
            split = (int(r.get("repeat", 0)), int(r["fold"]))  # rows of one run have no repeat
            out.setdefault((r["features"], int(r["M"])), {})[split] = r
    return out


def _rmse_change(a: dict[str, Any], b: dict[str, Any], dims: Sequence[str]) -> float:
    idx = [CH5_EFFECTS.index(d) for d in dims]
    return 100 * float(np.mean([a["rmse"][i] / b["rmse"][i] - 1 for i in idx]))


def _nlpd_change(a: dict[str, Any], b: dict[str, Any], dims: Sequence[str]) -> float:
    return float(np.sum(a["nlpd"]) - np.sum(b["nlpd"]))


def _row(
    cells: dict[tuple[str, int], dict[Split, dict[str, Any]]],
    claim: str,
    a: tuple[str, int],
    b: tuple[str, int],
    metric: str,
    dims: Sequence[str],
    thesis: str,
    *,
    direction: int,
    folds: int,
) -> dict[str, Any] | None:
    """One paired comparison of cells `a` and `b` over their shared splits (None if none)."""
    fa, fb = cells.get(a, {}), cells.get(b, {})
    splits = sorted(set(fa) & set(fb))
    if not splits:
        return None
    change = _rmse_change if metric.startswith("rmse") else _nlpd_change
    values = [change(fa[s], fb[s], dims) for s in splits]
    mean, hw = float(np.mean(values)), split_halfwidth(values, folds)
    return {
        "claim": claim,
        "a": f"{a[0]}, M={a[1]}",
        "b": f"{b[0]}, M={b[1]}",
        "metric": metric,
        "thesis": thesis,
        "repeats": len({r for r, _ in splits}),
        "folds": folds,
        "mean": mean,
        "ci95": hw,
        "verdict": verdict(mean, hw, direction, len(splits), _THESIS_SIZES.get(thesis)),
        "won": repeats_won(values, [r for r, _ in splits], direction),
    }


def chapter5_claims(results: list[dict[str, Any]], method: str = "em") -> list[dict[str, Any]]:
    """Chapter 5's claims on the study's fold rows (``ch5_folds.csv``), one row per comparison.

    Args:
        results: The chapter 5 split rows: ``features``, ``method``, ``M``, ``repeat``
            (0 where absent), ``fold``, ``rmse`` (6,) and ``nlpd`` (6,) in `CH5_EFFECTS`
            order.
        method: The method judged (``"em"``: the gated mixture).

    Returns:
        Rows of `CLAIM_COLUMNS`: the claim, the cells compared (``a`` against ``b``), the
        metric (``rmse %`` over the named effects, or ``nlpd`` in nats), the thesis's value,
        the repeats and folds, the mean paired difference over the splits, its 95 %
        half-width (`split_halfwidth`), the `verdict` and the share of repeats won
        (`repeats_won`).
        Comparisons whose cells were not run are left out.
    """
    cells = _by_split(results, method)
    feats = sorted({f for f, _ in cells})
    ms = sorted({m for _, m in cells})
    o2, more, best = "context features help o2", "M > 1 beats M = 1 on RMSE", "M = 3 is best"
    gate = "gate-on-context split best for o1 along the push"
    specs: list[tuple[str, tuple[str, int], tuple[str, int], str, Sequence[str], str]] = []
    for m in ms:
        specs.append((o2, ("ocx", m), ("o", m), "rmse % (o2)", _O2, "-11.8 %"))
        specs.append((o2, ("ocx", m), ("oc", m), "rmse % (o2)", _O2, "-4.37 %"))
    for feat in feats:
        for m in (m for m in ms if m != 1):
            specs.append(
                (more, (feat, m), (feat, 1), "rmse % (all)", CH5_EFFECTS, "-5.9 to -6.5 %")
            )
    for metric in ("rmse % (all)", "nlpd"):
        for feat in feats:
            for m in (m for m in ms if m != 3):
                specs.append((best, (feat, 3), (feat, m), metric, CH5_EFFECTS, "M = 3 lowest"))
    for m in (m for m in ms if m != 1):  # one expert has no gate: gx-eoc is oc there
        for other in ("ocx", "oc"):
            specs.append(
                (gate, ("gx-eoc", m), (other, m), "rmse % (o1 dz)", _O1_DZ, "gx-eoc lowest")
            )
    folds = study_folds([r for r in results if r["method"] == method])
    rows = [_row(cells, *spec, direction=-1, folds=folds) for spec in specs]
    return [r for r in rows if r is not None]


def claim_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The claims' Markdown: verdict counts per claim, then the comparisons at M = 3.

    For "M = 3 is best" the table keeps, per feature set and metric, the comparison least in
    its favour (against the runner-up M).
    """
    lines = []
    for claim in dict.fromkeys(r["claim"] for r in rows):
        mine = [r for r in rows if r["claim"] == claim]
        counts = {v: sum(r["verdict"] == v for r in mine) for v in VERDICTS}
        told = ", ".join(f"{n} {v}" for v, n in counts.items() if n)
        lines.append(f"- **{claim}**: {len(mine)} comparisons over every M: {told}.")
    at3 = [r for r in rows if r["a"].endswith("M=3") and r["claim"] != "M = 3 is best"]
    hardest: dict[tuple[str, str], dict[str, Any]] = {}
    for r in rows:
        if r["claim"] == "M = 3 is best":
            key = (r["metric"], r["a"].split(",")[0])
            if key not in hardest or r["mean"] > hardest[key]["mean"]:
                hardest[key] = r
    table = markdown_table([*at3, *hardest.values()], CLAIM_COLUMNS, digits=2)
    return [*lines, "", "At M = 3:", "", table]
