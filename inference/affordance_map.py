"""Affordance-map study (thesis chapter 3): information-gain pushing against exhaustive pushing.

Tables and figures (Figs. 3.5-3.7) go to results/affordance_map/. Every field of
`probaff.experiments.affordance_map.AffordanceMapConfig` (and of its `MRFParams`) is a flag
(``--help`` lists them); ``probaff study affordance_map`` runs the same.

    python inference/affordance_map.py [--n-maps N] [--workers K | --scheduler ADDR] [--smoke]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.affordance_map import SMOKE, Config, run
from probaff.experiments.config_cli import parse_study_args


def main() -> None:
    """Parse the command line into a study config and run it."""
    result = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": result["files"], "computed": result["computed"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
