"""A file is safe to hand to HDF5 before probaff parses it: a SHA-256 seal, or a probe.

HDF5 is a C library: a damaged file can crash it (a segmentation fault on a few flipped bytes
of an attribute's heap) or keep it reading without end, and neither can be caught in Python.
So nothing reaches h5py in probaff's process before one of these checks has passed:

* **Sealed files** (every file `probaff.data.hdf5.export_hdf5` writes). The file starts with
  an HDF5 *user block* of `USERBLOCK_BYTES` bytes, which HDF5 skips and every HDF5 reader
  accepts; probaff writes `SEAL_MAGIC` and the SHA-256 of every byte after the user block
  there, once the file is complete (`seal`). `check_hdf5_file` recomputes the digest
  (streamed, about 1 s per GB) and refuses a file whose bytes changed, before HDF5 sees it.
* **Other programs' files** (no seal). If the file holds HDF5's signature where HDF5 looks
  for it (else HDF5 refuses it unread), `check_hdf5_file` reads the whole file (the
  attributes of every object and every array) with h5py in a separate Python process first.
  If that process is killed by a signal or does not finish within `PROBE_SECONDS`, the file is
  refused; an ordinary error there is left to the caller's own reading, which names it.

A check that passed is remembered for the file's identity (path, device, inode, size and
modification time), so reading one row after another checks the file once.
"""

from __future__ import annotations

import functools
import hashlib
import os
import signal
import subprocess
import sys
from pathlib import Path

from probaff.errors import DatasetError

__all__ = ["PROBE_SECONDS", "SEAL_MAGIC", "USERBLOCK_BYTES", "check_hdf5_file", "seal"]

USERBLOCK_BYTES = 512
"""Size of the user block probaff's files start with (HDF5's smallest)."""
SEAL_MAGIC = b"probaff-hdf5 sha256 "
"""The user block's first bytes; the 64 hex digits of the digest and a newline follow."""
PROBE_SECONDS = 120.0
"""How long the separate process may take to read a file without a seal."""
_BLOCK = 1 << 20
_SIGNATURE = b"\x89HDF\r\n\x1a\n"

_PROBE = r"""
import sys
import h5py

def read(obj):
    for name in list(obj.attrs):
        obj.attrs[name]
    if isinstance(obj, h5py.Dataset) and obj.shape is not None:
        obj[()]

with h5py.File(sys.argv[1], "r") as fh:
    read(fh)
    fh.visititems(lambda name, obj: read(obj))
"""
"""What the separate process reads: every attribute and array, as an import does."""


def _digest(path: Path) -> str:
    """SHA-256 (hex) of the bytes of `path` after the user block."""
    h = hashlib.sha256()
    with path.open("rb") as fh:
        fh.seek(USERBLOCK_BYTES)
        for block in iter(lambda: fh.read(_BLOCK), b""):
            h.update(block)
    return h.hexdigest()


def seal(path: Path) -> None:
    """Write the seal of a complete HDF5 file created with ``userblock_size=USERBLOCK_BYTES``.

    Args:
        path: The file, closed by HDF5 (its user block still all zeros).

    Raises:
        OSError: If the file cannot be read or written.
    """
    text = SEAL_MAGIC + _digest(path).encode("ascii") + b"\n"
    with path.open("r+b") as fh:
        fh.write(text)


def _stored_digest(path: Path) -> str | None:
    """The digest in the seal of `path`, or None when the file has no seal."""
    with path.open("rb") as fh:
        head = fh.read(len(SEAL_MAGIC) + 65)
    if not head.startswith(SEAL_MAGIC):
        return None
    return head[len(SEAL_MAGIC) :].decode("ascii", errors="replace")


def _has_signature(path: Path) -> bool:
    """Whether `path` holds HDF5's superblock signature where HDF5 looks for it.

    HDF5 looks at byte 0, 512, 1024, 2048, ... (after a user block); a file without the
    signature is refused by HDF5 itself without parsing anything.
    """
    size, at = path.stat().st_size, 0
    with path.open("rb") as fh:
        while at + len(_SIGNATURE) <= size:
            fh.seek(at)
            if fh.read(len(_SIGNATURE)) == _SIGNATURE:
                return True
            at = USERBLOCK_BYTES if at == 0 else 2 * at
    return False


def _probe(path: Path) -> None:
    """Read `path` with h5py in a separate process; refuse it if that process crashes or hangs."""
    if not _has_signature(path):
        return
    cmd = [sys.executable, "-c", _PROBE, os.fspath(path)]
    try:
        done = subprocess.run(cmd, capture_output=True, timeout=PROBE_SECONDS, check=False)
    except subprocess.TimeoutExpired:
        raise DatasetError(
            f"{path} is damaged: reading it did not finish within {PROBE_SECONDS:.0f} s (HDF5 "
            "kept reading its metadata, in a separate process); export it again."
        ) from None
    if done.returncode < 0:
        try:
            name = signal.Signals(-done.returncode).name
        except ValueError:
            name = f"signal {-done.returncode}"
        raise DatasetError(
            f"{path} is damaged: reading it crashed HDF5 ({name}, in a separate process, so "
            "nothing was lost here); export it again."
        )


@functools.lru_cache(maxsize=256)
def _checked(path: str, identity: tuple[int, int, int, int]) -> None:
    """Run the check of `path` once per identity (device, inode, size, mtime); see module."""
    file = Path(path)
    stored = _stored_digest(file)
    if stored is None:
        _probe(file)
    elif _digest(file) != stored.strip():
        raise DatasetError(
            f"{file} is damaged: its bytes do not match the SHA-256 seal probaff wrote in its "
            f"first {USERBLOCK_BYTES} bytes (the user block); export it again."
        )


def check_hdf5_file(path: Path) -> None:
    """Refuse an HDF5 file that could crash or stall HDF5, before h5py opens it.

    Args:
        path: An existing file.

    Raises:
        DatasetError: Naming the file, if its seal does not match its bytes, or (without a
            seal) if reading it crashes or stalls HDF5 in a separate process.
        OSError: If the file cannot be read.
    """
    st = path.stat()
    _checked(os.fspath(path.resolve()), (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns))
