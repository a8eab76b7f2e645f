"""The planning study against a stored reference of success counts per planner.

A reference table (committed as ``benchmarks/reference/planning.csv``) is CSV with ``#``
comment lines and the columns ``part`` (``edge`` for push-to-edge, ``tool`` for tool push),
``planner`` (a name of `probaff.planning.EDGE_PLANNERS` or `TOOL_PUSH_PLANNERS`), ``trials``,
``successes`` and an optional free-text ``note``. `compare_successes` sets a run's summary
rows beside it, with the 95 % Wilson interval of each success rate, and flags a planner
whose success count fell below the reference's (its rate, where the run had other trial
counts). The episodes are seeded, so an unchanged code base repeats its counts exactly; any
fall is a change of behaviour, whether or not the intervals overlap.

``python inference/planning.py --reference FILE`` runs (or resumes) the study, writes the
comparison to ``out/reference_check.md`` (`check_run`) and exits with status 1 if a planner
fell.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from probaff._io import atomic_write_text, read_user_text
from probaff.errors import InputError
from probaff.eval.metrics import wilson_interval
from probaff.eval.tables import markdown_table
from probaff.planning import EDGE_PLANNERS, TOOL_PUSH_PLANNERS

__all__ = [
    "REFERENCE_COLUMNS",
    "check_run",
    "compare_successes",
    "fell",
    "load_reference",
    "parse_reference",
    "reference_section",
]

REFERENCE_COLUMNS = ("part", "planner", "trials", "successes")
"""The columns a reference table must have (``note`` may follow)."""

_PLANNERS: dict[str, Sequence[str]] = {"edge": tuple(EDGE_PLANNERS), "tool": TOOL_PUSH_PLANNERS}
"""The planners of each part of the study."""


def _count(value: str | None, what: str, where: str) -> int:
    """A non-negative integer cell."""
    try:
        n = int(value or "")
    except ValueError:
        n = -1
    if n < 0:
        raise InputError(f"{where}: {what} must be an integer >= 0, got {value!r}.")
    return n


def _row(record: dict[str | None, Any], where: str) -> dict[str, Any]:
    """One checked row of a reference table."""
    if None in record or any(record.get(c) is None for c in REFERENCE_COLUMNS):
        raise InputError(f"{where}: expected the cells {list(REFERENCE_COLUMNS)}, got {record}.")
    part, planner = record["part"].strip(), record["planner"].strip()
    if part not in _PLANNERS:
        raise InputError(f"{where}: unknown part {part!r}; choose from {list(_PLANNERS)}.")
    if planner not in _PLANNERS[part]:
        raise InputError(
            f"{where}: unknown {part} planner {planner!r}; choose from {list(_PLANNERS[part])}."
        )
    trials = _count(record["trials"], "trials", where)
    successes = _count(record["successes"], "successes", where)
    if trials < 1 or successes > trials:
        raise InputError(
            f"{where}: needs 1 <= trials and successes <= trials, got {successes}/{trials}."
        )
    return {"part": part, "planner": planner, "trials": trials, "successes": successes}


def parse_reference(text: str, name: str = "reference") -> list[dict[str, Any]]:
    """Read a reference table of success counts.

    Args:
        text: The table's text (``#`` lines are comments).
        name: How errors name it (e.g. ``"--reference FILE"``).

    Returns:
        One row per planner: ``part``, ``planner``, ``trials``, ``successes``.

    Raises:
        InputError: Naming `name`, for missing columns, an unknown part or planner, counts
            that are not integers with ``0 <= successes <= trials``, a planner listed twice,
            or no rows.
    """
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    try:
        reader = csv.DictReader(lines)
        header = list(reader.fieldnames or [])
        records = list(reader)
    except csv.Error as exc:
        raise InputError(f"{name} is not a readable CSV table ({exc}).") from None
    if header[: len(REFERENCE_COLUMNS)] != list(REFERENCE_COLUMNS):
        raise InputError(
            f"{name}: its columns are {header}, expected {list(REFERENCE_COLUMNS)} (then an "
            "optional note)."
        )
    rows: list[dict[str, Any]] = []
    for i, record in enumerate(records, start=1):
        row = _row(record, f"{name} row {i}")
        if any((r["part"], r["planner"]) == (row["part"], row["planner"]) for r in rows):
            raise InputError(f"{name} row {i}: {row['part']} planner {row['planner']!r} repeats.")
        rows.append(row)
    if not rows:
        raise InputError(f"{name} holds no planners; add a row per planner.")
    return rows


def load_reference(path: str | os.PathLike[str], option: str = "--reference") -> list[dict]:
    """Read the reference table at `path` (see `parse_reference`).

    Args:
        path: The file.
        option: How errors name it, with the path.

    Raises:
        InputError: For a missing, unreadable or malformed file.
    """
    name = f"{option} {os.fspath(path)}"
    missing = (
        "give a table of success counts per planner (benchmarks/reference/planning.csv is the "
        "committed one)."
    )
    return parse_reference(read_user_text(path, name, missing), name)


def _interval(successes: int, trials: int) -> dict[str, Any]:
    """Successes, trials, their rate and its 95 % Wilson interval (``low``, ``high``)."""
    lo, hi = wilson_interval(successes, trials)
    return {
        "successes": successes,
        "trials": trials,
        "rate": successes / trials,
        "low": lo,
        "high": hi,
    }


def compare_successes(
    reference: Sequence[dict[str, Any]],
    edge_rows: Sequence[dict[str, Any]] = (),
    tool_rows: Sequence[dict[str, Any]] = (),
) -> list[dict[str, Any]]:
    """Each planner's successes beside the reference's, with their Wilson intervals.

    Args:
        reference: Rows of `parse_reference` / `load_reference`.
        edge_rows: The run's push-to-edge summary (`report.summarise`; ``planner``,
            ``trials``, ``successes`` are read).
        tool_rows: The run's tool-push summary (`report.summarise_tool`).

    Returns:
        One row per reference planner, then per planner the reference lacks: ``part``,
        ``planner``, ``reference`` and ``now`` (each None or a dict of ``successes``,
        ``trials``, ``rate`` and the 95 % Wilson interval ``low``, ``high``) and ``status``:
        ``"fell"`` (fewer successes than the reference; where the trial counts differ, a
        lower rate), ``"same"``, ``"rose"``, ``"not run"`` (a reference planner the run
        lacks) or ``"no reference"``.

    Raises:
        InputError: For a summary row without ``planner``, ``trials`` or ``successes``.
    """
    now: dict[tuple[str, str], dict[str, Any]] = {}
    for part, rows in (("edge", edge_rows), ("tool", tool_rows)):
        for i, r in enumerate(rows):
            if not all(k in r for k in ("planner", "trials", "successes")):
                raise InputError(
                    f"{part}_rows[{i}] lacks planner, trials or successes; pass the rows of "
                    "summarise / summarise_tool."
                )
            now[(part, r["planner"])] = _interval(int(r["successes"]), int(r["trials"]))
    out = []
    for ref in reference:
        key = (ref["part"], ref["planner"])
        was, got = _interval(ref["successes"], ref["trials"]), now.pop(key, None)
        if got is None:
            status = "not run"
        else:
            # successes / trials against the reference's, without rounding
            diff = got["successes"] * was["trials"] - was["successes"] * got["trials"]
            status = "fell" if diff < 0 else "rose" if diff > 0 else "same"
        out.append(
            {"part": key[0], "planner": key[1], "reference": was, "now": got, "status": status}
        )
    out += [
        {"part": p, "planner": n, "reference": None, "now": got, "status": "no reference"}
        for (p, n), got in now.items()
    ]
    return out


def fell(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of `compare_successes` whose planner's success count fell."""
    return [r for r in rows if r["status"] == "fell"]


def _cell(counts: dict[str, Any] | None) -> str:
    """``k/n = rate [low, high]``, or ``-`` for None."""
    if counts is None:
        return "-"
    return (
        f"{counts['successes']}/{counts['trials']} = {counts['rate']:.2f} "
        f"[{counts['low']:.2f}, {counts['high']:.2f}]"
    )


def reference_section(rows: Sequence[dict[str, Any]], reference: str) -> list[str]:
    """`compare_successes` as Markdown lines: a heading, the table and its legend.

    Args:
        rows: What `compare_successes` returned.
        reference: The reference's name (its file).
    """
    table = [
        {
            "part": r["part"],
            "planner": r["planner"],
            "reference": _cell(r["reference"]),
            "now": _cell(r["now"]),
            "status": "**FELL**" if r["status"] == "fell" else r["status"],
        }
        for r in rows
    ]
    drops = [
        f"- {r['part']} planner {r['planner']} fell below the reference: "
        f"{_cell(r['now'])} against {_cell(r['reference'])}"
        for r in fell(rows)
    ]
    return [
        f"## Against the reference {reference}",
        "",
        markdown_table(table, ["part", "planner", "reference", "now", "status"]),
        "Cells: successes/trials = rate [95 % Wilson interval]. `fell`: fewer successes than "
        "the reference (a lower rate where the trial counts differ).",
        "",
        *([*drops, ""] if drops else []),
    ]


def check_run(
    reference: Sequence[dict[str, Any]],
    summary: dict[str, Any],
    out: str | os.PathLike[str],
    name: str,
) -> tuple[list[dict[str, Any]], list[str], str]:
    """Compare a run of the study with a reference and write ``out/reference_check.md``.

    Args:
        reference: Rows of `load_reference`.
        summary: What `probaff.experiments.planning.run` returned (``edge``, ``tool``).
        out: The study's output folder.
        name: The reference's name in the table's heading (its file).

    Returns:
        The rows of `compare_successes`, the Markdown lines of `reference_section`, and the
        written file's path.
    """
    rows = compare_successes(reference, summary.get("edge", ()), summary.get("tool", ()))
    lines = reference_section(rows, name)
    path = Path(out) / "reference_check.md"
    atomic_write_text(path, "\n".join(lines))
    return rows, lines, str(path)
