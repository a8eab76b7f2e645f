"""Push-model study (thesis chapters 5 and 4): EM and VI mixtures of GP experts.

Cross-validated tables and figures go to results/push_models/.

    python inference/push_models.py [--workers K | --scheduler ADDR] [--smoke]
"""

import argparse
import json

from probaff.studies.push_models import PushModelStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/push_models")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=0, help="local Dask workers (0: in process)")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument("--methods", default="em,vi", help="comma-separated: em, vi")
    p.add_argument("--no-ch4", action="store_true", help="skip the chapter 4 part")
    p.add_argument("--gate", default="linear", help="gate of the EM mixture: linear, fourier")
    p.add_argument("--exact-poses", action="store_true",
                   help="record exact poses (no pose-measurement noise)")
    p.add_argument("--smoke", action="store_true", help="a tiny run that checks the pipeline")
    a = p.parse_args()
    cfg = PushModelStudyConfig(out=a.out, seed=a.seed, workers=a.workers, scheduler=a.scheduler,
                               methods=tuple(a.methods.split(",")),
                               ch4_pushes=0 if a.no_ch4 else 120, gate=a.gate,
                               pose_noise=not a.exact_poses)
    if a.smoke:
        cfg = PushModelStudyConfig(
            out=a.out, seed=a.seed, workers=a.workers, scheduler=a.scheduler,
            methods=tuple(a.methods.split(",")), ch5_pushes=40, ch5_experts=(1, 2),
            ch5_folds=2, ch5_features=("ocx", "gx-eoc"), ch4_pushes=0 if a.no_ch4 else 24,
            ch4_experts=(1, 2), ch4_folds=2, ch4_features=("oc",), em_iterations=2,
            em_restarts=2, vi_features=("gx-eoc",), vi_steps=30, gp_max_iter=8,
            progress=False)
    summary = run(cfg)
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    main()
