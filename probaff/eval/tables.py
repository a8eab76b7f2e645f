"""Result tables: CSV and Markdown text from rows of dicts, written atomically."""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Sequence
from typing import Any

from probaff._io import atomic_write_text

__all__ = ["csv_table", "group_rows", "markdown_table", "write_csv"]


def csv_table(rows: Sequence[dict[str, Any]]) -> str:
    """CSV text with a header from the first row's keys (every row has the same keys).

    Args:
        rows: At least one row.

    Returns:
        The CSV text.

    Raises:
        ValueError: If `rows` is empty.
    """
    if not rows:
        raise ValueError("a table needs at least one row.")
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
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
    """
    head = "| " + " | ".join(columns) + " |\n|" + "---|" * len(columns) + "\n"
    body = ""
    for r in rows:
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
        InputError: If `path` is a folder, lies under a regular file or in a folder that
            cannot be written.
    """
    flat = [{k: v for k, v in r.items() if not isinstance(v, list)} for r in rows]
    atomic_write_text(path, csv_table(flat), name="path")
    return os.fspath(path)
