"""Push-model study (thesis chapters 5 and 4): EM and VI mixtures of GP experts.

Cross-validated tables and figures go to results/push_models/. Every field of
`probaff.studies.push_models.PushModelStudyConfig` is a flag (``--help`` lists them).

    python inference/push_models.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import study_config, study_parser
from probaff.studies.push_models import SMOKE_OVERRIDES, PushModelStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = study_parser(PushModelStudyConfig, __doc__)
    p.add_argument(
        "--exact-poses",
        action="store_true",
        help="record exact poses (the same as --no-pose-noise)",
    )
    p.add_argument("--no-ch4", action="store_true", help="skip chapter 4 (--ch4-pushes 0)")
    a = p.parse_args()
    extra: dict[str, object] = {}
    if a.exact_poses:
        extra["pose_noise"] = False
    if a.no_ch4:
        extra["ch4_pushes"] = 0
    summary = run(study_config(PushModelStudyConfig, a, SMOKE_OVERRIDES, **extra))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
