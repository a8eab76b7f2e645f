"""Charts of chapter 6's errors: along a chain, modular against monolithic, learning curves.

Every chart is a pure function of summary rows (dicts, or the same values loaded back from
JSON). Errors are in centimetres, coverages are fractions, intervals are half-widths.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator, NullLocator, PercentFormatter

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.eval.plots import (
    axes_grid,
    check_figure_path,
    check_records,
    check_unique,
    finite_number,
    half_width,
    nonempty_text,
    save_titled,
)

__all__ = ["plot_chain_errors", "plot_learning_curves", "plot_modular_vs_monolithic"]

_CHAIN_KEYS = ("n_objects", "object", "error_cm", "error_ci", "coverage90", "coverage_ci")
_BAR_KEYS = ("model", "object", "axis", "error_cm", "error_ci")
_CURVE_KEYS = ("panel", "series", "train_size", "value", "ci")
_AXES = ("along", "off")
_MODEL_COLOURS = {"modular": "tab:blue", "monolithic": "tab:orange"}
_CYCLE = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


# --- errors along a chain --------------------------------------------------------------------


def _chain_rows(rows: Any) -> list[dict[str, Any]]:
    records = check_records("rows", rows, _CHAIN_KEYS, "chain-error rows")
    out = []
    for i, r in enumerate(records):
        where = f"rows[{i}]"
        n = check_count(f"{where}['n_objects']", r["n_objects"])
        place = check_count(f"{where}['object']", r["object"])
        if place > n:
            raise InputError(
                f"{where}['object'] is {place} but the chain has {n} object(s) "
                "(n_objects); objects are numbered 1..n_objects from the hand."
            )
        coverage = finite_number(f"{where}['coverage90']", r["coverage90"])
        if not 0 <= coverage <= 1:
            raise InputError(
                f"{where}['coverage90'] must be a fraction in [0, 1] (not percent), got {coverage}."
            )
        error = finite_number(f"{where}['error_cm']", r["error_cm"])
        if error < 0:
            raise InputError(f"{where}['error_cm'] must be >= 0 (a distance in cm), got {error}.")
        out.append(
            {
                "n_objects": n,
                "object": place,
                "error_cm": error,
                "error_ci": half_width(f"{where}['error_ci']", r["error_ci"]),
                "coverage90": coverage,
                "coverage_ci": half_width(f"{where}['coverage_ci']", r["coverage_ci"]),
            }
        )
    check_unique("rows", [(r["n_objects"], r["object"]) for r in out], "(n_objects, object)")
    return out


def _chain_colours(lengths: Sequence[int]) -> dict[int, Any]:
    """A colour per chain length, light to dark along the viridis map."""
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    if len(lengths) == 1:
        return {lengths[0]: cmap(0.35)}
    return {n: cmap(0.85 * j / (len(lengths) - 1)) for j, n in enumerate(lengths)}


def plot_chain_errors(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Error and coverage of chained predictions against each object's place in the chain.

    Two panels. Left: the mean position error (cm) of each object against its place in the
    chain (1 is the object the hand pushes), one line per chain length with 95 % error bars.
    Right: the 90 % interval coverage of each object, same layout, with the nominal 90 % as
    a dashed line. Lines of different chain lengths are set slightly apart so their bars do
    not hide one another.

    Args:
        rows: One per (chain length, object) with keys ``n_objects`` (int, the chain
            length), ``object`` (int, 1-based place in the chain), ``error_cm`` and
            ``error_ci`` (the 95 % half-width, cm), ``coverage90`` and ``coverage_ci``
            (fractions in [0, 1]).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, a count that is not a positive
            integer, an object placed beyond its chain, a coverage outside [0, 1], a
            negative or non-finite value, or two rows of the same chain length and object.
    """
    check_figure_path(path)
    parsed = _chain_rows(rows)
    lengths = sorted({r["n_objects"] for r in parsed})
    colours = _chain_colours(lengths)
    fig = Figure(figsize=(9.0, 3.9), layout="constrained")
    err_ax, cov_ax = fig.subplots(1, 2)
    offsets = 0.06 * (np.arange(len(lengths)) - (len(lengths) - 1) / 2)
    for n, dx in zip(lengths, offsets, strict=True):
        mine = sorted((r for r in parsed if r["n_objects"] == n), key=lambda r: r["object"])
        x = np.array([r["object"] for r in mine], dtype=float) + dx
        style = {"color": colours[n], "marker": "o", "ms": 4, "capsize": 3, "lw": 1.5}
        label = f"{n} object{'s' if n > 1 else ''}"
        for ax, value, ci in (
            (err_ax, "error_cm", "error_ci"),
            (cov_ax, "coverage90", "coverage_ci"),
        ):
            y, yerr = [r[value] for r in mine], [r[ci] for r in mine]
            ax.errorbar(x, y, yerr=yerr, label=label, **style)
    nominal = cov_ax.axhline(0.9, color="k", ls="--", lw=1, label="nominal 90 %")
    cov_ax.set_ylim(0, 1.05)
    cov_ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    cov_ax.set_ylabel("90 % interval coverage")
    err_ax.set_ylim(bottom=0)
    err_ax.set_ylabel("mean position error (cm)")
    for ax in (err_ax, cov_ax):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlim(0.5, max(lengths) + 0.5)
        ax.set_xlabel("place in the chain (1 = pushed by the hand)")
        ax.grid(alpha=0.3)
    err_ax.set_title("position error (bars: 95 % interval)", fontsize=9)
    cov_ax.set_title("coverage of the 90 % interval (bars: 95 % interval)", fontsize=9)
    handles = [*cov_ax.containers, nominal]
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
    return save_titled(fig, path, title, "Chained push predictions along the chain")


# --- modular against monolithic --------------------------------------------------------------


def _bar_rows(rows: Any) -> list[dict[str, Any]]:
    records = check_records("rows", rows, _BAR_KEYS, "model-error rows")
    out = []
    for i, r in enumerate(records):
        where = f"rows[{i}]"
        axis = r["axis"]
        if axis not in _AXES:
            raise InputError(f"{where}['axis'] must be one of {list(_AXES)}, got {axis!r}.")
        error = finite_number(f"{where}['error_cm']", r["error_cm"])
        if error < 0:
            raise InputError(f"{where}['error_cm'] must be >= 0 (an absolute error), got {error}.")
        out.append(
            {
                "model": nonempty_text(f"{where}['model']", r["model"]),
                "object": check_count(f"{where}['object']", r["object"]),
                "axis": str(axis),
                "error_cm": error,
                "error_ci": half_width(f"{where}['error_ci']", r["error_ci"]),
            }
        )
    check_unique(
        "rows", [(r["model"], r["object"], r["axis"]) for r in out], "(model, object, axis)"
    )
    return out


def _thesis_values(
    thesis: Any, bars: Mapping[tuple[str, int, str], Any]
) -> dict[tuple[str, int, str], float]:
    """The thesis's values keyed like `bars`; every key must name a drawn bar."""
    if not isinstance(thesis, Mapping):
        raise InputError(
            f"thesis must map (model, object, axis) to a value in cm, got {type(thesis).__name__}."
        )
    out = {}
    for key, value in thesis.items():
        name = f"thesis[{key!r}]"
        if not (isinstance(key, tuple) and len(key) == 3):
            raise InputError(f"{name}: keys must be (model, object, axis) tuples.")
        norm = (key[0], check_count(f"{name} object", key[1]), key[2])
        if norm not in bars:
            raise InputError(
                f"{name} matches no bar; the rows give (model, object, axis) in {sorted(bars)}."
            )
        check_positive(name, value, allow_zero=True)
        out[norm] = float(value)
    return out


def _model_colours(models: Sequence[str]) -> dict[str, str]:
    """The modular and monolithic models keep their colours; the others take free ones."""
    free = [c for c in _CYCLE if c not in {_MODEL_COLOURS.get(m) for m in models}]
    out = {}
    for m in models:
        out[m] = _MODEL_COLOURS[m] if m in _MODEL_COLOURS else free.pop(0) if free else "0.5"
    return out


def plot_modular_vs_monolithic(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    thesis: Mapping[tuple[str, int, str], float] | None = None,
    title: str | None = None,
) -> str:
    """Mean absolute error per object and axis, one bar per model, and save the figure.

    Groups are the objects (o1 is the one the hand pushes) and the axis of the error,
    ``along`` or ``off`` the push; each model has a bar in each group with its 95 % error
    bar and value written above. The modular model is blue and the monolithic orange, as in
    `plot_tabletop_predictions`. Values reported in the thesis are black ticks across the
    matching bars.

    Args:
        rows: One per (model, object, axis) with keys ``model`` (str), ``object`` (int,
            1-based), ``axis`` (``"along"`` or ``"off"``), ``error_cm`` and ``error_ci``
            (the 95 % half-width, cm).
        path: Image file to write (format from the suffix), atomically.
        thesis: Optional ``{(model, object, axis): value_cm}``, e.g.
            ``{("modular", 1, "along"): 1.89, ("monolithic", 1, "along"): 4.83}``.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, an unknown axis, an object that is
            not a positive integer, a negative or non-finite value, two rows of the same
            model, object and axis, or a thesis entry that matches no bar.
    """
    check_figure_path(path)
    parsed = _bar_rows(rows)
    bars = {(r["model"], r["object"], r["axis"]): r for r in parsed}
    marks = {} if thesis is None else _thesis_values(thesis, bars)
    models = list(dict.fromkeys(r["model"] for r in parsed))
    groups = sorted(
        {(r["object"], r["axis"]) for r in parsed}, key=lambda g: (g[0], _AXES.index(g[1]))
    )
    colours = _model_colours(models)
    width = 0.8 / len(models)
    wide = 1.4 + 1.25 * len(groups) * max(1.0, len(models) / 2)
    fig = Figure(figsize=(max(5.0, wide), 4.0), layout="constrained")
    ax = fig.subplots()
    top = 0.0
    handles: list[Any] = []
    for m, model in enumerate(models):
        xs, heights, cis = [], [], []
        for g, (obj, axis) in enumerate(groups):
            row = bars.get((model, obj, axis))
            if row is not None:
                xs.append(g + (m - (len(models) - 1) / 2) * width)
                heights.append(row["error_cm"])
                cis.append(row["error_ci"])
        drawn = ax.bar(xs, heights, width * 0.92, yerr=cis, color=colours[model], capsize=3)
        drawn.set_label(model)
        handles.append(drawn)
        for x, h, ci in zip(xs, heights, cis, strict=True):
            ax.annotate(
                f"{h:.2f}",
                (x, h + ci),
                xytext=(0, 2),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=6,
            )
            top = max(top, h + ci)
    if marks:
        centres = np.array(
            [
                groups.index((obj, axis)) + (models.index(model) - (len(models) - 1) / 2) * width
                for model, obj, axis in marks
            ]
        )
        values = np.array(list(marks.values()))
        ticks = ax.hlines(
            values,
            centres - 0.45 * width,
            centres + 0.45 * width,
            color="k",
            lw=2.5,
            zorder=5,
            label="thesis",
        )
        handles.append(ticks)
        top = max(top, float(values.max()))
    ax.set_xticks(
        range(len(groups)), [f"o{obj}\n{axis} the push" for obj, axis in groups], fontsize=8
    )
    ax.set_xlim(-0.6, len(groups) - 0.4)
    ax.set_ylim(0, 1.15 * top if top > 0 else 1.0)
    ax.set_ylabel("mean absolute error (cm)")
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
    return save_titled(fig, path, title, "Push prediction error, 95 % interval")


# --- learning curves -------------------------------------------------------------------------


def _curve_rows(rows: Any) -> list[dict[str, Any]]:
    records = check_records("rows", rows, _CURVE_KEYS, "learning-curve rows")
    out = [
        {
            "panel": nonempty_text(f"rows[{i}]['panel']", r["panel"]),
            "series": nonempty_text(f"rows[{i}]['series']", r["series"]),
            "train_size": check_count(f"rows[{i}]['train_size']", r["train_size"]),
            "value": finite_number(f"rows[{i}]['value']", r["value"]),
            "ci": half_width(f"rows[{i}]['ci']", r["ci"]),
        }
        for i, r in enumerate(records)
    ]
    check_unique(
        "rows", [(r["panel"], r["series"], r["train_size"]) for r in out], "(panel, series, size)"
    )
    return out


def _unit(panel: str) -> str:
    """The y label of a panel: "error" with the unit the panel name ends in, if any."""
    found = re.search(r"\(([^()]+)\)\s*$", panel)
    return f"error ({found.group(1)})" if found else "error"


def plot_learning_curves(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Error against training-set size, one panel per quantity, and save the figure.

    Each panel (e.g. ``"push o1 along (cm)"``) has a line per series with its 95 % band; a
    series keeps its colour in every panel. The x axis is logarithmic when a panel's sizes
    span more than a factor of 4, its ticks at the sizes measured. Panels come three to a
    row; the y label takes the unit the panel name ends in, in parentheses.

    Args:
        rows: One per (panel, series, training-set size) with keys ``panel`` and
            ``series`` (str), ``train_size`` (int), ``value`` and ``ci`` (its 95 %
            half-width, in the panel's unit).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, a non-string panel or series, a size
            that is not a positive integer, a non-finite value, a negative half-width or two
            rows of the same panel, series and size.
    """
    check_figure_path(path)
    parsed = _curve_rows(rows)
    panels = list(dict.fromkeys(r["panel"] for r in parsed))
    series = list(dict.fromkeys(r["series"] for r in parsed))
    colours = {s: _CYCLE[j % len(_CYCLE)] for j, s in enumerate(series)}
    n = len(panels)
    cols = min(3, n)
    fig = Figure(figsize=(4.0 * cols, 3.3 * math.ceil(n / cols) + 0.7), layout="constrained")
    for ax, panel in zip(axes_grid(fig, n, cols), panels, strict=True):
        mine = [r for r in parsed if r["panel"] == panel]
        for s in series:
            pts = sorted((r for r in mine if r["series"] == s), key=lambda r: r["train_size"])
            if not pts:
                continue
            x = np.array([r["train_size"] for r in pts], dtype=float)
            y = np.array([r["value"] for r in pts])
            ci = np.array([r["ci"] for r in pts])
            ax.fill_between(x, y - ci, y + ci, color=colours[s], alpha=0.18, lw=0)
            ax.plot(x, y, color=colours[s], marker="o", ms=4, lw=1.5, label=s)
            if len(x) == 1:  # a band of one point does not show; draw its interval as a bar
                ax.errorbar(x, y, yerr=ci, color=colours[s], capsize=3, lw=1.5)
        sizes = sorted({r["train_size"] for r in mine})
        if sizes[-1] > 4 * sizes[0]:
            ax.set_xscale("log")
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xticks(sizes, [str(s) for s in sizes], fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.set_xlabel("training-set size (samples)", fontsize=8)
        ax.set_ylabel(_unit(panel), fontsize=8)
        ax.set_title(panel, fontsize=9)
        ax.grid(alpha=0.3)
    handles: list[Any] = [
        Line2D([], [], color=colours[s], marker="o", ms=4, lw=1.5, label=s) for s in series
    ]
    handles.append(Patch(fc="0.5", alpha=0.3, label="95 % interval"))
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 5), fontsize=8)
    return save_titled(fig, path, title, "Learning curves, 95 % intervals")
