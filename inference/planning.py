"""Planning study (thesis chapters 4 and 5): push-to-edge and tool-push planners, closed loop.

Tables and figures go to results/planning/. Every field of
`probaff.experiments.planning.PlanningStudyConfig` is a flag (``--help`` lists them);
``probaff study planning`` runs the same.

    python inference/planning.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.planning import SMOKE, Config, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    summary = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
