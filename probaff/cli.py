"""The `probaff` command: generate, describe, scenes, export, import, demo, study."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from probaff._cli_errors import report_error
from probaff.errors import ProbaffError

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the `probaff` command."""
    p = argparse.ArgumentParser(prog="probaff", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    g = sub.add_parser(
        "generate", help="simulate a push or pick/place dataset (sharded, resumable)"
    )
    g.add_argument(
        "--scene",
        required=True,
        help="scene template (see `probaff scenes`): a tabletop scene gives pushes, a side-view "
        "scene picks or places",
    )
    g.add_argument("--n", type=int, required=True, help="number of pushes (or picks, places)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out", required=True, help="dataset folder to create")
    g.add_argument(
        "--workers",
        type=int,
        default=None,
        help="local Dask workers (default: one per core; 0 = run in this process)",
    )
    g.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    g.add_argument("--shard-size", type=int, default=64)
    g.add_argument("--no-trajectories", action="store_true", help="do not store trajectories")
    g.add_argument(
        "--pose-noise",
        metavar="POS_M,YAW_DEG",
        default=None,
        help="record object poses with Gaussian measurement noise of these standard "
        "deviations (metres, degrees), e.g. 0.003,1; exact values are kept in "
        "the true_* arrays (default: exact poses); tabletop scenes only",
    )
    g.add_argument(
        "--record-rate",
        type=float,
        default=None,
        metavar="HZ",
        help="samples per second of the stored trajectories; side-view scenes only (default: "
        "the world's record rate)",
    )
    g.add_argument(
        "--hand",
        choices=["stiff", "compliant"],
        default=None,
        help="how the hand follows its command: held to it, or a spring with a force limit "
        "that yields to resistance (default: the world file's hand.mode)",
    )
    g.add_argument("--resume", action="store_true", help="finish an interrupted dataset")
    g.add_argument("--quiet", action="store_true", help="no progress bar")

    d = sub.add_parser("describe", help="print a JSON summary of a dataset of any kind")
    d.add_argument("path")

    sub.add_parser("scenes", help="list the scene templates of every world kind")

    x = sub.add_parser("export", help="write a push or skill dataset to one HDF5 file")
    x.add_argument("dataset", help="dataset folder")
    x.add_argument("--to", required=True, metavar="FILE.h5", help="HDF5 file to write")

    i = sub.add_parser(
        "import", help="write a dataset folder from an HDF5 file (layout: probaff.data.hdf5)"
    )
    i.add_argument("file", metavar="FILE.h5", help="HDF5 file to read")
    i.add_argument("--out", required=True, help="dataset folder to create")
    i.add_argument(
        "--shard-size", type=int, default=None, help="rows per shard (default: the file's, or 64)"
    )

    m = sub.add_parser(
        "demo",
        help="the main job on a small default: pushes, models, maps, planning, skills and "
        "point clouds, printed as a short report ending with its figures",
    )
    m.add_argument("--out", default="results/demo")
    m.add_argument("--n", type=int, default=96)
    m.add_argument("--seed", type=int, default=0)
    m.add_argument("--workers", type=int, default=0)
    m.add_argument(
        "--office-scenes",
        type=int,
        default=None,
        help="office scenes of the chapter 2 part, the held-out one included (default 23: "
        "22 train the label classifiers)",
    )
    m.add_argument("--quiet", action="store_true", help="no progress bar")

    sub.add_parser(
        "study",
        help="run one study: probaff study NAME [--smoke] [--FIELD VALUE ...] "
        "(probaff study --help lists them)",
        add_help=False,
    )
    return p


def _hdf5(args: argparse.Namespace) -> None:
    """``probaff export`` and ``probaff import``: a dataset to and from an HDF5 file."""
    from probaff.data.hdf5 import export_hdf5, import_hdf5
    from probaff.data.store import read_manifest

    if args.command == "export":
        export_hdf5(args.dataset, args.to)
        rows = read_manifest(args.dataset)["plan"]["n"]
        print(f"wrote {rows} rows of {args.dataset} to {args.to}")
    else:
        out = import_hdf5(args.file, args.out, shard_size=args.shard_size)
        print(f"wrote {read_manifest(out)['plan']['n']} rows of {args.file} to {out}")


def _dispatch(args: argparse.Namespace) -> None:
    if args.command == "generate":
        from probaff._checks import check_output_dir

        check_output_dir("--out", args.out)  # before the simulator is loaded
        from probaff.data.config import GenerateConfig
        from probaff.data.generation import generate
        from probaff.data.noise import parse_pose_noise

        noise = None if args.pose_noise is None else parse_pose_noise(args.pose_noise)
        cfg = GenerateConfig(
            scene=args.scene,
            n=args.n,
            seed=args.seed,
            shard_size=args.shard_size,
            trajectories=not args.no_trajectories,
            pose_noise=noise,
            record_rate=args.record_rate,
            hand=args.hand,
        )
        ds = generate(
            cfg,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            resume=args.resume,
            progress=not args.quiet,
        )
        print(f"wrote {len(ds)} {ds.rows_label} to {args.out}")
    elif args.command == "describe":
        from pathlib import Path

        from probaff.data.kinds import dataset_kind
        from probaff.data.store import load_any_dataset, manifest_kind, read_manifest

        kind = dataset_kind(manifest_kind(read_manifest(Path(args.path))))
        print(json.dumps(kind.summarize(load_any_dataset(args.path)), indent=1))
    elif args.command == "scenes":
        from probaff.sim.registry import world_kinds

        for world in world_kinds():
            for name in world.scene_names():
                print(f"{name:16s} {world.describe(name)}")
    elif args.command in ("export", "import"):
        _hdf5(args)
    elif args.command == "demo":
        from probaff._checks import check_output_dir

        check_output_dir("--out", args.out)
        from probaff.demo import DemoConfig, run

        run(
            DemoConfig(
                out=args.out,
                n=args.n,
                seed=args.seed,
                workers=args.workers,
                **({} if args.office_scenes is None else {"office_scenes": args.office_scenes}),
                progress=not args.quiet,
            )
        )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; errors that probaff raises on purpose print one clear line.

    ``probaff study NAME ...`` hands everything after ``study`` to the study's own parser
    (`probaff.experiments.study_main`).

    Returns:
        The exit status: 0 on success, 2 for a probaff error.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["study"]:
        from probaff.experiments import study_main

        return study_main(argv[1:])
    args = build_parser().parse_args(argv)
    try:
        _dispatch(args)
    except ProbaffError as exc:
        return report_error(f"probaff {args.command}", exc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
