"""Affordance-map study (thesis chapter 3): information-gain pushing against exhaustive pushing.

Tables and figures (Figs. 3.5-3.7) go to results/affordance_map/. Every field of
`probaff.studies.affordance_map.AffordanceMapConfig` (and of its `MRFParams`) is a flag
(``--help`` lists them).

    python inference/affordance_map.py [--n-maps N] [--workers K | --scheduler ADDR] [--smoke]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.affordance_map import AffordanceMapConfig, run
from probaff.studies.config_cli import study_config, study_parser

SMOKE = {"n_maps": 2, "train_maps": 2, "max_steps": 3, "progress": False}


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = study_parser(AffordanceMapConfig, __doc__)
    p.add_argument(
        "--no-stop",
        action="store_true",
        help="keep the information-gain loop pushing when every gain is negative "
        "(the same as --no-stop-at-no-gain)",
    )
    a = p.parse_args()
    extra = {"stop_at_no_gain": False} if a.no_stop else {}
    result = run(study_config(AffordanceMapConfig, a, SMOKE, **extra))
    print(json.dumps({"files": result["files"], "computed": result["computed"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
