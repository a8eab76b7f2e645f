"""Push-model study (thesis chapters 5 and 4): EM and VI mixtures of GP experts.

Cross-validated tables and figures go to results/push_models/. Every field of
`probaff.experiments.push_models.PushModelStudyConfig` is a flag (``--help`` lists them);
``probaff study push_models`` runs the same.

    python inference/push_models.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.push_models import SMOKE, Config, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    summary = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
