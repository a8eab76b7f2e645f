"""HDF5 export and import of a large push dataset, against the store's sharded ``.npz`` files.

The dataset is synthesised with numpy, not simulated (simulating 100 000 pushes takes hours):
every array of the push schema (`probaff.data.schema`, pose noise and trajectories included)
in its shape and dtype, with plausible values (poses on a 1 x 0.8 m table, straight-line
trajectories from the start to the end pose, clouds of points
around each object's pose with unit normals, random flags), so sizes and times are those of
a real dataset of that shape, but compression ratios are those of random numbers, which
compress less than a simulator's (many exact zeros and repeats).

Side by side, for the store's ``.npz`` shards (`probaff.data.save_dataset`,
`probaff.data.load_dataset`) and the HDF5 file (`probaff.data.export_hdf5`, plain h5py reads):

  write       the in-memory dataset to disk,
  read all    every array back into memory,
  read one    one push (npz: its whole shard is inflated; HDF5: one chunk of each array,
              `probaff.data.hdf5.read_row`, after it checks the file's SHA-256 seal once:
              `probaff.data.hdf5_guard`),
  read another  the next push (the file already checked),
  size        on disk,

with the ratio HDF5 / npz. Then the two commands end to end: ``probaff export`` (load the
folder, write the file) and ``probaff import`` (read the file, check every array as a robot's
input, write the shards). Times are wall-clock seconds of one run.

Usage: python benchmarks/hdf5_io.py [--n 100000] [--objects 2] [--points 64] [--samples 32]
"""

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from probaff.data import (
    PushDataset,
    export_hdf5,
    import_hdf5,
    load_dataset,
    save_dataset,
)
from probaff.data.hdf5 import read_row
from probaff.data.queries import world_meta
from probaff.data.schema import GROUND_TRUTH_ARRAYS
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop


def synthesise(n: int, k: int, p: int, t: int, seed: int = 0) -> PushDataset:
    """N pushes of K objects in the push schema's shapes and dtypes (random, not simulated)."""
    rng = np.random.default_rng(seed)
    names = sorted(load_catalogue())
    before = rng.uniform([-0.4, -0.3, -np.pi], [0.4, 0.3, np.pi], (n, k, 3))
    after = before + rng.normal(0.0, [0.02, 0.02, 0.1], (n, k, 3))
    yaw = rng.uniform(-np.pi, np.pi, n)
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]

    def effect(before: np.ndarray, after: np.ndarray) -> np.ndarray:
        """The pushing-frame (dy_p, dz_p, dtheta_p) of each push (what the schema stores)."""
        d = after - before
        return np.stack(
            [-d[..., 0] * s + d[..., 1] * c, d[..., 0] * c + d[..., 1] * s, d[..., 2]], axis=-1
        )

    frac = np.linspace(0.0, 1.0, t)[None, :, None, None]  # (1, T, 1, 1)
    origin = before[:, 0, :2] - 0.1 * np.concatenate([c, s], axis=1)  # (N, 2)
    step = 0.2 * frac[:, :, 0, 0, None] * np.concatenate([c, s], axis=1)[:, None]  # (N, T, 2)
    hand = np.concatenate([origin[:, None] + step, np.repeat(yaw[:, None, None], t, 1)], -1)
    normals = rng.normal(size=(n, k, p, 3))
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    points = before[:, :, None, :].copy().repeat(p, axis=2)
    points[..., 2] = 0.0
    points += rng.uniform(-0.05, 0.05, (n, k, p, 3))
    arrays = {
        "object_ids": rng.integers(0, len(names), (n, k)).astype(np.int16),
        "state_before": before,
        "state_after": after,
        "effect": effect(before, after),
        "push_origin": origin,
        "push_yaw": yaw,
        "push_distance": np.full(n, 0.2),
        "q_waypoints": rng.uniform(-3.0, 3.0, (n, 7, 6)),
        "mass": rng.uniform(0.1, 1.0, (n, k)),
        "ground_friction": rng.uniform(0.2, 0.6, (n, k)),
        "contact_friction": rng.uniform(0.2, 0.6, (n, k)),
        "support_weights": rng.uniform(0.0, 1.0, (n, k, 9)),
        "walls": np.zeros((n, 0, 4)),
        "hand_contact": rng.random((n, k)) < 0.9,
        "object_contact": rng.random((n, k, k)) < 0.2,
        "wall_contact": np.zeros((n, k), dtype=bool),
        "fell_off": rng.random((n, k)) < 0.05,
        "hand_lag": rng.uniform(0.0, 0.01, n),
        "max_penetration": rng.uniform(0.0, 0.002, n),
        "cloud_points": points.astype(np.float32),
        "cloud_normals": normals.astype(np.float32),
        "traj_time": np.tile(np.arange(t) / 20.0, (n, 1)),
        # straight-line paths from the start to the end pose (observation checks refuse jumps)
        "traj_hand": hand.astype(np.float32),
        "traj_objects": (before[:, None] + frac * (after - before)[:, None]).astype(np.float32),
    }
    true = [before + rng.normal(0.0, 0.003, (n, k, 3)), after + rng.normal(0.0, 0.003, (n, k, 3))]
    true.append(effect(*true))  # exact values beside the noisy observations
    arrays.update(zip(GROUND_TRUTH_ARRAYS, true, strict=True))
    meta = {"scene": "synthetic", **world_meta(load_tabletop())}
    meta["pose_noise"] = {"position_std": 0.003, "yaw_std": 0.003}
    return PushDataset(arrays, names, meta)


def _timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _size(path: Path) -> float:
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    return sum(p.stat().st_size for p in files) / 1e6


def _read_h5(file: Path) -> dict[str, np.ndarray]:
    with h5py.File(file, "r") as fh:
        return {name: dset[()] for name, dset in fh["data"].items()}


def _read_npz_row(folder: Path, index: int, shard_size: int) -> dict[str, np.ndarray]:
    shard = folder / "shards" / f"{index // shard_size:05d}.npz"
    with np.load(shard) as npz:
        return {name: npz[name][index % shard_size] for name in npz.files}


def main() -> None:
    ap = argparse.ArgumentParser(description="HDF5 export and import against the npz shards")
    sizes = {"n": 100_000, "objects": 2, "points": 64, "samples": 32, "shard-size": 64}
    for flag, default in sizes.items():
        ap.add_argument(f"--{flag}", type=int, default=default, help=f"default {default}")
    args = ap.parse_args()
    ds = synthesise(args.n, args.objects, args.points, args.samples)
    in_memory = sum(a.nbytes for a in ds.arrays.values()) / 1e6
    root = Path(tempfile.mkdtemp(prefix="probaff-hdf5-bench-"))
    try:
        npz, h5 = root / "npz", root / "ds.h5"
        row = args.n // 2 + 7
        write = (
            _timed(lambda: save_dataset(ds, npz, shard_size=args.shard_size))[0],
            _timed(lambda: export_hdf5(ds, h5))[0],
        )
        read = (_timed(lambda: load_dataset(npz))[0], _timed(lambda: _read_h5(h5))[0])
        one = (
            _timed(lambda: _read_npz_row(npz, row, args.shard_size))[0] * 1e3,
            _timed(lambda: read_row(h5, row))[0] * 1e3,  # checks the file's seal first
        )
        again = (
            _timed(lambda: _read_npz_row(npz, row + 1, args.shard_size))[0] * 1e3,
            _timed(lambda: read_row(h5, row + 1))[0] * 1e3,  # the file already checked
        )
        size = (_size(npz), _size(h5))
        assert all(np.array_equal(v, ds[k][row]) for k, v in read_row(h5, row).items()), (
            "a row read back differs"
        )
        export_s, _ = _timed(lambda: export_hdf5(npz, root / "exported.h5"))
        import_s, _ = _timed(lambda: import_hdf5(root / "exported.h5", root / "imported"))
        same = all(
            (npz / p.relative_to(root / "imported")).read_bytes() == p.read_bytes()
            for p in (root / "imported").rglob("*")
            if p.is_file()
        )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(
        f"{args.n} pushes, K = {args.objects}, P = {args.points}, T = {args.samples}, "
        f"{len(ds.arrays)} arrays, {in_memory:.0f} MB in memory "
        "(synthesised with numpy, not simulated)"
    )
    print(f"{'':22s} {'npz shards':>11s} {'hdf5':>9s} {'hdf5 / npz':>11s}")
    for label, (a, b), unit in (
        ("write", write, "s"),
        ("read all", read, "s"),
        ("read one push", one, "ms"),
        ("read another", again, "ms"),
        ("size on disk", size, "MB"),
    ):
        print(f"{label + ' (' + unit + ')':22s} {a:11.3f} {b:9.3f} {b / a:11.2f}")
    print(f"probaff export, folder -> file: {export_s:.2f} s (load the shards, write the file)")
    print(
        f"probaff import, file -> folder: {import_s:.2f} s (read, check every array, write "
        f"the shards); shards and manifest byte-identical to the original: {same}"
    )


if __name__ == "__main__":
    main()
