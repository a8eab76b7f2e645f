"""Result tables: CSV and Markdown text from rows of dicts, written atomically."""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from probaff._checks import check_count
from probaff._io import atomic_write_text
from probaff.errors import InputError

__all__ = ["csv_table", "group_rows", "markdown_table", "write_csv"]


def _table_rows(rows: Any) -> list[Mapping[str, Any]]:
    """`rows` as a list of mappings, or `InputError` naming ``rows`` (or the first bad row)."""
    if isinstance(rows, (str, bytes, Mapping)) or not isinstance(rows, Iterable):
        raise InputError(
            f"rows must be a list of {{column: value}} rows, got {type(rows).__name__}."
        )
    out = list(rows)
    for i, row in enumerate(out):
        if not isinstance(row, Mapping):
            raise InputError(
                f"rows[{i}] must be a {{column: value}} mapping, got {type(row).__name__}."
            )
    return out


def csv_table(rows: Sequence[dict[str, Any]]) -> str:
    """CSV text with a header from the first row's keys (every row has the same keys).

    Args:
        rows: At least one row; a row may lack a column of the first (its cell is empty).

    Returns:
        The CSV text.

    Raises:
        InputError: If `rows` is empty or not a list of mappings, or a row holds a column
            that the first row lacks.
    """
    table = _table_rows(rows)
    if not table:
        raise InputError("rows is empty; a table needs at least one row.")
    fields = list(table[0])
    for i, row in enumerate(table):
        extra = [k for k in row if k not in table[0]]
        if extra:
            raise InputError(
                f"rows[{i}] holds columns {extra} that the first row lacks; give every row "
                "the first row's columns."
            )
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields)
    writer.writeheader()
    writer.writerows(table)
    return buf.getvalue()


def group_rows(rows: Iterable[dict[str, Any]], key: str) -> dict[Any, list[dict[str, Any]]]:
    """The rows of each value of column `key`, values in the order they first appear.

    Args:
        rows: Rows that all hold `key`.
        key: The column to group by.

    Returns:
        Value of `key` -> its rows, in their order in `rows`.
    """
    out: dict[Any, list[dict[str, Any]]] = {}
    for r in rows:
        out.setdefault(r[key], []).append(r)
    return out


def markdown_table(rows: Sequence[dict[str, Any]], columns: Sequence[str], digits: int = 4) -> str:
    """A Markdown table of `columns` of `rows`, floats with `digits` decimals.

    Args:
        rows: The rows, in order.
        columns: The keys shown, in order.
        digits: Decimals of float cells.

    Returns:
        The table's text, one line per row after the header.

    Raises:
        InputError: If `rows` is not a list of mappings, `columns` not a list of names, a
            row lacks one of them, or `digits` is not an integer >= 0.
    """
    table = _table_rows(rows)
    if isinstance(columns, str) or not all(isinstance(c, str) for c in columns):
        raise InputError(f"columns must be a list of column names, got {columns!r}.")
    digits = check_count("digits", digits, minimum=0)
    for i, row in enumerate(table):
        missing = [c for c in columns if c not in row]
        if missing:
            raise InputError(f"rows[{i}] lacks the column(s) {missing} the table shows.")
    head = "| " + " | ".join(columns) + " |\n|" + "---|" * len(columns) + "\n"
    body = ""
    for r in table:
        cells = [f"{r[c]:.{digits}f}" if isinstance(r[c], float) else str(r[c]) for c in columns]
        body += "| " + " | ".join(cells) + " |\n"
    return head + body


def write_csv(path: str | os.PathLike[str], rows: Sequence[dict[str, Any]]) -> str:
    """Write `rows` as CSV to `path` atomically, dropping list-valued columns.

    Args:
        path: Destination file.
        rows: At least one row; values that are lists (per-sample data) are left out.

    Returns:
        `path` as a string.

    Raises:
        InputError: If `rows` is not a non-empty list of mappings (see `csv_table`), or
            `path` is a folder, lies under a regular file or in a folder that cannot be
            written.
    """
    flat = [{k: v for k, v in r.items() if not isinstance(v, list)} for r in _table_rows(rows)]
    atomic_write_text(path, csv_table(flat), name="path")
    return os.fspath(path)
