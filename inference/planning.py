"""Planning study (thesis chapter 4): push-to-edge planners closed loop in the simulator.

Tables and figures go to results/planning/. Every field of
`probaff.studies.planning.PlanningStudyConfig` is a flag (``--help`` lists them).

    python inference/planning.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import study_config, study_parser
from probaff.studies.planning import SMOKE_OVERRIDES, PlanningStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    args = study_parser(PlanningStudyConfig, __doc__).parse_args()
    summary = run(study_config(PlanningStudyConfig, args, SMOKE_OVERRIDES))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
