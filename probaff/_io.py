"""Atomic file output, and reading a small text file that a user named.

A crash while writing leaves either the old file or the whole new one, never a part.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

from probaff._checks import check_output_file
from probaff.errors import InputError

__all__ = ["atomic_save_figure", "atomic_write_bytes", "atomic_write_text", "read_user_text"]


def read_user_text(path: str | os.PathLike[str], name: str, missing: str) -> str:
    """The UTF-8 text of a file a user named, or one clear error.

    Args:
        path: The file.
        name: How errors name it (e.g. ``"--reference results/ref.csv"``).
        missing: The fix a missing file's error suggests.

    Raises:
        InputError: Naming `name`, for a missing, unreadable or non-UTF-8 file.
    """
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{name} does not exist; {missing}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name} cannot be read ({exc}).") from None


def atomic_write_bytes(
    path: str | os.PathLike[str], data: bytes, *, name: str | None = None
) -> None:
    """Write `data` to `path` through a flushed temporary file and a rename.

    Missing parent folders are created.

    Args:
        path: The file.
        data: Its new content.
        name: How an error names the path (e.g. ``"result file"``). Given, the path is
            checked first (`probaff._checks.check_output_file`), so that a bad one is named in
            an `InputError`; public writers give it.

    Raises:
        InputError: With `name`, for a path that is a folder, lies under a regular file or in
            a folder that cannot be written.
        OSError: If the file cannot be written (a file in the way, a full disk, ...).
    """
    path = check_output_file(name, path) if name is not None else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str, *, name: str | None = None) -> None:
    """Write UTF-8 `text` to `path` atomically (see `atomic_write_bytes`, and its `name`)."""
    atomic_write_bytes(path, text.encode("utf-8"), name=name)


def atomic_save_figure(fig: Any, path: str | os.PathLike[str], **savefig_kwargs: Any) -> None:
    """Save a matplotlib figure to `path` atomically (format from the suffix).

    Raises:
        InputError: If `path` is a folder, lies under a regular file or in a folder that
            cannot be written (checked before the figure is rendered).
    """
    target = check_output_file("path", path)
    buf = io.BytesIO()
    fmt = target.suffix.lstrip(".") or "png"
    fig.savefig(buf, format=fmt, **savefig_kwargs)
    atomic_write_bytes(target, buf.getvalue())
