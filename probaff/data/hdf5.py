"""HDF5 in and out: a push or skill dataset as one ``.h5`` file, in a documented layout.

`export_hdf5` writes a dataset folder (or an in-memory dataset) to one HDF5 file;
`import_hdf5` reads such a file, written by probaff or by any other program, checks it and
writes a dataset folder (`probaff.data.store`). ``probaff export DATASET --to FILE.h5`` and
``probaff import FILE.h5 --out DATASET`` run them.

Layout (``format`` ``"probaff-hdf5"``, ``format_version`` 1)::

    FILE.h5
      user block             the first 512 bytes, which HDF5 skips: "probaff-hdf5 sha256 ",
                             the SHA-256 of the rest of the file and a newline
                             (`probaff.data.hdf5_guard`: a damaged file is refused before
                             HDF5 reads it; absent from other programs' files, which are
                             read once in a separate process first)
      /data                  group; its attributes:
        format               "probaff-hdf5"
        format_version       1
        kind                 "push" or "skill" (default "push")
        object_names         JSON list: the names ``object_ids`` index (required)
        meta                 JSON object: what the features read about the world (pushes:
                             push_height, gripper_opening, finger_radius, table_size; skills:
                             skill, lift, ...), the scene's name, ... (default {})
        manifest             JSON: the dataset folder's manifest.json (written by probaff;
                             absent from other programs' files)
        world_yaml           text of the world description the data was simulated in
                             (worlds/tabletop.yaml, worlds/sideview.yaml), when known
        scene_yaml           text of the scene template (worlds/scenes/NAME.yaml, ...)
        checksum             SHA-256 of the text attributes above (`_text_digest`: kind,
                             object_names, meta, manifest, world_yaml, scene_yaml), written
                             by probaff and checked on import when present, since HDF5
                             keeps no checksum of attribute values (absent from other
                             programs' files)
      /data/<array>          one dataset per array of the schema (`probaff.data.schema`,
                             `probaff.data.skill_schema`), first axis the row (push or
                             skill), the schema's dtype; its attribute:
        units                the array's units, as `probaff.data.schema.ARRAY_UNITS` and
                             `probaff.data.skill_schema.SKILL_ARRAY_UNITS` give them: one unit
                             ("m", "rad", "1", "index", "bool") or one per component of the
                             last axis ("m, m, rad")

A file from another program needs only the ``object_names`` attribute and the observation
arrays (`probaff.data.schema.OBSERVATION_ARRAYS` less ``effect``, ``walls`` and the clouds,
which may be replaced by ``object_size`` boxes; `probaff.data.skill_schema.
SKILL_OBSERVATION_ARRAYS`), each with its ``units``; everything else is optional
(`probaff.data.observations.observation_dataset`, which checks the arrays on import).

Why one dataset per array rather than one group per push: a push is one step, not an episode
(robomimic's ``data/demo_i`` groups hold episodes of hundreds of steps), and 100 000 pushes as
groups would be two million HDF5 objects, whose headers alone outweigh the data and take
minutes to create and to list. One dataset per array keeps a file to a few dozen objects,
compresses across pushes, and still lets a reader take one push without reading the file:
arrays are chunked along the row axis, each chunk whole rows of about `CHUNK_BYTES`, so
``f["data/effect"][i]`` (or `read_row`) reads one chunk of each array. Chunks are compressed
with gzip (``shuffle`` first; gzip, unlike lzf, every HDF5 reader has) and carry a Fletcher-32
checksum, so a corrupted chunk fails to read instead of giving wrong numbers. Attributes use
dense storage (HDF5 1.8 file format), so a long manifest or YAML fits.

Round trip. Exporting a dataset folder stores its manifest; importing the file writes the same
shards (same shard size, same bytes) and the same manifest, byte for byte. A file without a
manifest gets a new one (`probaff.data.store.save_dataset`). Both directions write atomically:
the file or folder appears whole under its name, or not at all, and an import refuses a
folder that already holds something.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from probaff._checks import check_count, check_output_dir, check_output_file
from probaff.data.dataset import ArrayDataset
from probaff.data.hdf5_guard import USERBLOCK_BYTES, check_hdf5_file, seal
from probaff.data.kinds import kind_of_dataset
from probaff.data.observations import observation_dataset
from probaff.data.schema import PushDataset
from probaff.data.skill_schema import SkillDataset
from probaff.data.store import check_new_dataset_folder, load_any_dataset, read_manifest
from probaff.data.store import save_dataset as _save
from probaff.errors import ConfigError, DatasetError, InputError, ProbaffError
from probaff.sim.registry import kind_of_scene
from probaff.sim.world_files import worlds_dir

if TYPE_CHECKING:
    import h5py

__all__ = [
    "CHUNK_BYTES",
    "HDF5_FORMAT",
    "HDF5_FORMAT_VERSION",
    "export_hdf5",
    "import_hdf5",
    "read_row",
]

HDF5_FORMAT = "probaff-hdf5"
"""The ``format`` attribute of ``/data``."""
HDF5_FORMAT_VERSION = 1
"""The ``format_version`` attribute of ``/data``."""
CHUNK_BYTES = 64 * 1024
"""Target size of a chunk (bytes, uncompressed): whole rows, at least one."""
_COMPRESSION_LEVEL = 4
_CLASSES: dict[str, type[ArrayDataset]] = {"push": PushDataset, "skill": SkillDataset}


def _h5py() -> Any:
    """The h5py module, imported when HDF5 is first used (so that probaff imports without it).

    Raises:
        ConfigError: If h5py is not installed.
    """
    try:
        import h5py
    except ImportError as exc:
        raise ConfigError(
            f"HDF5 import and export need h5py ({exc}); install it with `pip install h5py`."
        ) from None
    return h5py


def _chunks(arr: np.ndarray) -> tuple[int, ...] | None:
    """Chunks of whole rows of about `CHUNK_BYTES`; ``None`` (contiguous) for an empty array."""
    if arr.size == 0:
        return None
    row = max(1, arr[:1].nbytes)
    return (max(1, min(len(arr), CHUNK_BYTES // row)), *arr.shape[1:])


def _world_texts(scene: Any) -> dict[str, str]:
    """The world description and scene template of `scene`, as text, when this install has them."""
    try:
        world = kind_of_scene(scene)
        files = {"world_yaml": worlds_dir() / f"{world.name}.yaml"}
        if world.scenes is not None:
            files["scene_yaml"] = world.scene_path(scene)
    except ProbaffError:
        return {}
    return {k: p.read_text() for k, p in files.items() if p.is_file()}


def _write_file(path: Path, ds: ArrayDataset, manifest: dict[str, Any] | None, level: int) -> None:
    kind = kind_of_dataset(ds).name
    with _h5py().File(path, "w", libver=("v108", "latest"), userblock_size=USERBLOCK_BYTES) as fh:
        data = fh.create_group("data")
        attrs = {
            "format": HDF5_FORMAT,
            "format_version": HDF5_FORMAT_VERSION,
            "kind": kind,
            "n_rows": len(ds),
            "object_names": json.dumps(list(ds.object_names)),
            "meta": json.dumps(ds.meta if manifest is None else manifest["meta"], sort_keys=True),
            **_world_texts(ds.meta.get("scene")),
        }
        if manifest is not None:
            attrs["manifest"] = json.dumps(manifest, indent=1, sort_keys=True) + "\n"
        attrs["checksum"] = _text_digest({k: v for k, v in attrs.items() if k in _CHECKED})
        data.attrs.update(attrs)
        for name in sorted(ds.arrays):
            arr = np.ascontiguousarray(ds.arrays[name])
            chunks = _chunks(arr)
            options: dict[str, Any] = {}
            if chunks is not None:
                options = {
                    "chunks": chunks,
                    "compression": "gzip",
                    "compression_opts": level,
                    "shuffle": True,
                    "fletcher32": True,
                }
            dset = data.create_dataset(name, data=arr, **options)
            dset.attrs["units"] = ds.UNITS.get(name, "1")


def export_hdf5(
    source: ArrayDataset | str | os.PathLike[str],
    file: str | os.PathLike[str],
    *,
    compression_level: int = _COMPRESSION_LEVEL,
) -> Path:
    """Write a push or skill dataset to one HDF5 file (layout: the module docstring).

    Args:
        source: A dataset folder (its manifest is stored too, so `import_hdf5` restores it
            byte for byte) or an in-memory dataset (its ``meta`` is stored; an import makes a
            new manifest).
        file: The ``.h5`` file to write; it is replaced atomically if it exists.
        compression_level: gzip level, 1 (fast) to 9 (small).

    Returns:
        `file` as a `Path`.

    Raises:
        InputError: For a `file` that is a folder or cannot be written there, a bad level, or
            a `source` that is neither a dataset nor a path.
        DatasetError: If the dataset folder is incomplete or corrupt (`load_any_dataset`), or
            the file cannot be written.
    """
    target = check_output_file("file", file)
    level = check_count("compression_level", compression_level)
    if level > 9:
        raise InputError(f"compression_level must be 1 to 9, got {compression_level!r}.")
    if isinstance(source, ArrayDataset):
        ds, manifest = source, None
    elif isinstance(source, (str, os.PathLike)):
        manifest = read_manifest(Path(source))
        ds = load_any_dataset(source)
    else:
        raise InputError(
            f"source must be a dataset folder or a dataset, got {type(source).__name__}."
        )
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        _write_file(tmp, ds, manifest, level)
        seal(tmp)
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise DatasetError(
            f"cannot write {target} ({exc}); choose a file you may write to, with free space."
        ) from exc
    return target


_CHECKED = ("kind", "object_names", "meta", "manifest", "world_yaml", "scene_yaml")
"""The text attributes of /data that the ``checksum`` attribute covers."""


def _text_digest(texts: dict[str, Any]) -> str:
    """SHA-256 (hex) of the text attributes `texts` (name to text), in a fixed order."""
    blob = json.dumps({k: texts[k] for k in _CHECKED if k in texts}, sort_keys=True)
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()


def _verify_checksum(data: h5py.Group, file: Path, reading: _Reading) -> None:
    """Refuse a file whose text attributes do not match its ``checksum`` attribute (if any).

    Raises:
        DatasetError: Naming the file and the attributes, when they were damaged or edited.
    """
    reading.at = "attribute 'checksum' of /data"
    stored = _text_attr(data, file, "checksum")
    if stored is None:
        return
    texts: dict[str, Any] = {}
    for name in _CHECKED:
        reading.at = f"attribute {name!r} of /data"
        text = _text_attr(data, file, name)
        if text is not None:
            texts[name] = text
    if _text_digest(texts) != stored:
        raise DatasetError(
            f"{file}: the attributes {sorted(texts)} of /data do not match the SHA-256 "
            "checksum stored with them (attribute 'checksum'): the file was damaged or edited "
            "after probaff wrote it; export it again."
        )


_H5PY_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError)
"""What h5py raises on a damaged file: HDF5's own errors surface as these built-in types."""


class _Reading:
    """Where in a file a read is: the group, dataset or attribute named when it fails."""

    def __init__(self, file: Path) -> None:
        self.file = file
        self.at = "the file's superblock"

    @contextmanager
    def boundary(self) -> Iterator[None]:
        """Turn any error h5py raises inside into one `DatasetError` naming the file and `at`.

        Errors probaff raises on purpose (`ProbaffError`) pass unchanged.

        Raises:
            DatasetError: For an h5py error (`_H5PY_ERRORS`): the file is damaged where the
                message says.
        """
        try:
            yield
        except ProbaffError:
            raise
        except _H5PY_ERRORS as exc:
            why = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
            raise DatasetError(
                f"{self.file}: {self.at} cannot be read: the file is truncated or corrupted "
                f"({type(exc).__name__}: {why}); export it again."
            ) from None


def _text_attr(data: h5py.Group, file: Path, name: str) -> str | None:
    """Attribute `name` of ``/data`` as text, ``None`` when absent."""
    if name not in data.attrs:
        return None
    value = data.attrs[name]
    if isinstance(value, bytes):
        value = value.decode("utf-8", errors="surrogateescape")
    if not isinstance(value, str):
        raise DatasetError(
            f"{file}: attribute {name!r} of /data is {type(value).__name__}, expected text."
        )
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:  # h5py and the decode above keep bad bytes as surrogates
        raise DatasetError(
            f"{file}: attribute {name!r} of /data is not valid UTF-8 text: the file is damaged "
            "or was written with another encoding; export it again (as UTF-8)."
        ) from None
    return value


def _json_attr(data: h5py.Group, file: Path, name: str, kind: type, default: Any) -> Any:
    text = _text_attr(data, file, name)
    if text is None:
        if default is None:
            raise DatasetError(
                f"{file}: /data lacks the attribute {name!r}; expected a JSON "
                f"{'list of names' if kind is list else 'object'} (see probaff.data.hdf5)."
            )
        return default
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{file}: attribute {name!r} of /data is not JSON ({exc}).") from None
    if not isinstance(value, kind):
        raise DatasetError(
            f"{file}: attribute {name!r} of /data is a JSON {type(value).__name__}, expected a "
            f"JSON {'list' if kind is list else 'object'}."
        )
    return value


def _open(file: Path) -> h5py.File:
    if not file.is_file():
        raise DatasetError(f"{file} does not exist or is not a file; give an HDF5 file.")
    try:
        check_hdf5_file(file)
        return _h5py().File(file, "r")
    except DatasetError:
        raise
    except OSError as exc:
        raise DatasetError(
            f"{file} is not a readable HDF5 file: it is truncated, corrupted or of another "
            f"format ({exc}); export it again."
        ) from None


def _data_group(fh: h5py.File, file: Path, reading: _Reading) -> h5py.Group:
    reading.at = "group /data"
    data = fh.get("data")
    if not isinstance(data, _h5py().Group):
        raise DatasetError(
            f"{file} has no group '/data' (or its metadata is damaged); the layout puts every "
            "array under /data and the dataset's description in its attributes (see "
            "probaff.data.hdf5)."
        )
    reading.at = "attribute 'format' of /data"
    fmt = _text_attr(data, file, "format")
    if fmt is not None and fmt != HDF5_FORMAT:
        raise DatasetError(f"{file}: /data has format {fmt!r}, expected {HDF5_FORMAT!r}.")
    reading.at = "attribute 'format_version' of /data"
    version = data.attrs.get("format_version", HDF5_FORMAT_VERSION)
    if not isinstance(version, (int, np.integer)) or version != HDF5_FORMAT_VERSION:
        raise DatasetError(
            f"{file}: /data has format_version {version!r}, but this probaff reads version "
            f"{HDF5_FORMAT_VERSION}; import it with the probaff release that wrote it."
        )
    return data


def _read_arrays(
    data: h5py.Group,
    file: Path,
    cls: type[ArrayDataset],
    rows: Any = (),
    reading: _Reading | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Every array under /data (or row `rows` of each) with its units, checked by name.

    `reading`, when given, is kept at the object being read (for `_Reading.boundary`).
    """
    known = {**cls.REQUIRED, **cls.OPTIONAL}
    arrays, units = {}, {}
    if reading is not None:
        reading.at = "the list of arrays under /data"
    for name, item in data.items():
        if reading is not None:
            reading.at = f"/data/{name}"
        if not isinstance(item, _h5py().Dataset):
            raise DatasetError(
                f"{file}: /data/{name} is a group, expected an array: arrays are datasets "
                "directly under /data (see probaff.data.hdf5)."
            )
        if name not in known:
            raise DatasetError(
                f"{file}: /data/{name} is not a {cls.KIND} array; the {cls.KIND} arrays are "
                f"{sorted(known)}."
            )
        if item.shape is None or len(item.shape) == 0:
            raise DatasetError(
                f"{file}: /data/{name} is a scalar (or empty) dataset, expected an array with "
                "one row per push or skill (first axis the row; see probaff.data.hdf5)."
            )
        if reading is not None:
            reading.at = f"attribute 'units' of /data/{name}"
        unit = item.attrs.get("units")
        if isinstance(unit, bytes):
            unit = unit.decode("utf-8", errors="replace")
        if unit is None:
            raise DatasetError(
                f"{file}: /data/{name} has no 'units' attribute; expected "
                f"{cls.UNITS[name]!r} (see probaff.data.hdf5)."
            )
        if reading is not None:
            reading.at = f"the chunk index of /data/{name}"
        _check_chunks(item, f"/data/{name}", file, rows)
        if reading is not None:
            reading.at = f"/data/{name}"
        try:
            arrays[name] = np.asarray(item[rows])
        except (OSError, ValueError, TypeError) as exc:
            raise DatasetError(
                f"{file}: /data/{name} cannot be read: the file is truncated or corrupted "
                f"({exc}); export it again."
            ) from None
        units[name] = str(unit)
    return arrays, units


def _check_chunks(item: h5py.Dataset, where: str, file: Path, rows: Any) -> None:
    """Refuse a chunked array whose chunks to be read are not all stored, intact and whole.

    HDF5 reads a chunk missing from its index as fill values (zeros) and one whose filter
    mask skips a filter unfiltered, with no error; a damaged chunk index (which carries no
    checksum in this layout's HDF5 1.8 format) does both. Every chunk of an array (or the
    one of row `rows`, an int) must therefore be found, by its coordinates, with every
    filter applied. Each chunk's stored bytes are read once more for this (compressed, so
    a fraction of the array's size).

    Raises:
        DatasetError: Naming the file and the array.
    """
    chunks = item.chunks
    if chunks is None or item.size == 0:
        return
    shape, dsid = item.shape, item.id
    grid = [range(0, n, c) for n, c in zip(shape, chunks, strict=True)]
    if isinstance(rows, (int, np.integer)):
        first = int(rows) // chunks[0] * chunks[0]
        grid[0] = range(first, first + 1)
    missing, skipped = 0, 0
    for coord in itertools.product(*grid):
        # as a read looks chunks up (get_chunk_info_by_coord misses a damaged index key)
        try:
            mask, _ = dsid.read_direct_chunk(tuple(int(v) for v in coord))
        except (RuntimeError, KeyError, OSError, ValueError):
            missing += 1
            continue
        skipped += bool(mask)
    if missing or skipped:
        raise DatasetError(
            f"{file}: {where} has {missing} chunk(s) missing from its chunk index and "
            f"{skipped} stored with a filter skipped, which HDF5 would read as zeros or "
            "unfiltered bytes without an error; the file is damaged (or was written only in "
            "part): export it again, writing every row."
        )


def import_hdf5(
    file: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    shard_size: int | None = None,
) -> Path:
    """Read an HDF5 file in the documented layout and write it as a dataset folder.

    Every array is checked as `probaff.data.observations.observation_dataset` checks a
    robot's arrays (dtype, shape, units, frames, finiteness), against the ``units``
    attribute the file gives it. Nothing is written until the whole file has been read and
    checked, and the folder is written atomically.

    Args:
        file: The ``.h5`` file.
        out: The dataset folder to create; it must not exist, or be an empty folder.
        shard_size: Rows per shard; by default the stored manifest's, else 64.

    Returns:
        `out` as a `Path`.

    Raises:
        InputError: For an `out` that is a file, lies under one or cannot be written, or a
            bad `shard_size`.
        DatasetError: If `out` already holds a dataset or other files; if the file is
            missing, truncated, corrupted or not HDF5; or if it is not in the layout (no
            ``/data`` group, a missing or malformed attribute, an unknown array, a missing
            ``units`` attribute, an array of the wrong dtype, shape or units, NaN or inf, ...;
            the message names the array or attribute and what was expected).

    Example:
        Four simulated pushes out to one HDF5 file and back into a dataset folder:

        >>> import shutil
        >>> import tempfile
        >>> from pathlib import Path
        >>> from probaff.data import GenerateConfig, export_hdf5, generate, import_hdf5
        >>> from probaff.data import load_dataset
        >>> tmp = Path(tempfile.mkdtemp())
        >>> config = GenerateConfig("two_objects", 4, seed=0)
        >>> ds = generate(config, tmp / "pushes", workers=0, progress=False)
        >>> export_hdf5(tmp / "pushes", tmp / "pushes.h5").name
        'pushes.h5'
        >>> copy = load_dataset(import_hdf5(tmp / "pushes.h5", tmp / "copy"))
        >>> len(copy), bool((copy["effect"] == ds["effect"]).all())
        (4, True)
        >>> shutil.rmtree(tmp)
    """
    path = check_output_dir("out", out)
    if shard_size is not None:
        shard_size = check_count("shard_size", shard_size)
    check_new_dataset_folder(path)
    source = Path(os.fspath(file))
    reading = _Reading(source)
    with reading.boundary(), _open(source) as fh:
        data = _data_group(fh, source, reading)
        _verify_checksum(data, source, reading)
        kind = _kind(data, source, reading)
        if kind not in _CLASSES:
            raise DatasetError(
                f"{source}: attribute 'kind' of /data is {kind!r}, expected one of "
                f"{sorted(_CLASSES)}."
            )
        reading.at = "attribute 'object_names' of /data"
        names = _json_attr(data, source, "object_names", list, None)
        reading.at = "attribute 'meta' of /data"
        meta = _json_attr(data, source, "meta", dict, {})
        reading.at = "attribute 'manifest' of /data"
        manifest = _json_attr(data, source, "manifest", dict, {}) or None
        arrays, units = _read_arrays(data, source, _CLASSES[kind], reading=reading)
        reading.at = "the file's metadata (on closing it)"
    try:
        ds: ArrayDataset = (
            observation_dataset(arrays, names, meta, kind="skill", units=units)
            if kind == "skill"
            else observation_dataset(arrays, names, meta, units=units)
        )
    except InputError as exc:
        raise DatasetError(f"{source} (/data): {exc}") from None
    if manifest is not None:
        if shard_size is not None:
            manifest = {**manifest, "plan": {**manifest["plan"], "shard_size": shard_size}}
        return _save(ds, path, manifest=manifest)
    return _save(ds, path, shard_size=64 if shard_size is None else shard_size)


def read_row(file: str | os.PathLike[str], index: int) -> dict[str, np.ndarray]:
    """One row (push or skill) of an HDF5 file, reading one chunk of each array.

    Args:
        file: An ``.h5`` file in the layout of the module docstring.
        index: The row, 0 to N - 1.

    Returns:
        Every array's row `index` (the first axis dropped).

    Raises:
        InputError: For an index out of range.
        DatasetError: As `import_hdf5`, for a file that cannot be read or is not in the
            layout (the row's values are not checked).
    """
    source = Path(os.fspath(file))
    index = check_count("index", index, minimum=0)
    reading = _Reading(source)
    with reading.boundary(), _open(source) as fh:
        data = _data_group(fh, source, reading)
        _verify_checksum(data, source, reading)
        cls = _CLASSES.get(_kind(data, source, reading), PushDataset)
        rows = _row_count(data, source, reading)
        if index >= rows:
            raise InputError(f"index must be below the file's {rows} rows, got {index}.")
        arrays, _ = _read_arrays(data, source, cls, index, reading)
        reading.at = "the file's metadata (on closing it)"
    return arrays


def _kind(data: h5py.Group, file: Path, reading: _Reading) -> str:
    """The ``kind`` attribute of /data (``"push"`` when absent)."""
    reading.at = "attribute 'kind' of /data"
    return _text_attr(data, file, "kind") or "push"


def _row_count(data: h5py.Group, file: Path, reading: _Reading) -> int:
    """The rows of the arrays under /data, which must all have the same first axis.

    Raises:
        DatasetError: Naming a scalar array, or two arrays whose row counts disagree.
    """
    counts: dict[str, int] = {}
    for name, item in data.items():
        reading.at = f"/data/{name}"
        if not isinstance(item, _h5py().Dataset):
            continue
        if item.shape is None or len(item.shape) == 0:
            raise DatasetError(
                f"{file}: /data/{name} is a scalar (or empty) dataset, expected an array with "
                "one row per push or skill (first axis the row; see probaff.data.hdf5)."
            )
        counts[name] = int(item.shape[0])
    if len(set(counts.values())) > 1:
        (a, n), (b, m) = sorted(counts.items(), key=lambda kv: (kv[1], kv[0]))[:: len(counts) - 1]
        raise DatasetError(
            f"{file}: the arrays under /data disagree in their number of rows (/data/{a} has "
            f"{n}, /data/{b} has {m}); every array has one row per push or skill: write them "
            "again with the same rows."
        )
    return next(iter(counts.values()), 0)
