"""Push-model study (thesis chapters 5 and 4): EM and VI mixtures of GP experts.

Cross-validated tables and figures go to results/push_models/. Every field of
`probaff.studies.push_models.PushModelStudyConfig` is a flag (``--help`` lists them).

    python inference/push_models.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import argparse
import dataclasses
import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import add_config_arguments, config_from_args
from probaff.studies.push_models import SMOKE_OVERRIDES, PushModelStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(p, PushModelStudyConfig)
    p.add_argument(
        "--exact-poses",
        action="store_true",
        help="record exact poses (the same as --no-pose-noise)",
    )
    p.add_argument("--no-ch4", action="store_true", help="skip chapter 4 (--ch4-pushes 0)")
    p.add_argument(
        "--smoke",
        action="store_true",
        help="a tiny run that checks the pipeline (sizes from SMOKE_OVERRIDES; "
        "the other flags still apply)",
    )
    a = p.parse_args()
    cfg = config_from_args(PushModelStudyConfig, a)
    if a.smoke:
        cfg = dataclasses.replace(cfg, **SMOKE_OVERRIDES)
    if a.exact_poses:
        cfg = dataclasses.replace(cfg, pose_noise=False)
    if a.no_ch4:
        cfg = dataclasses.replace(cfg, ch4_pushes=0)
    summary = run(cfg)
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
