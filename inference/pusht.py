"""Push-T study: learned push models and a planner in the unmodified gym-pusht environment.

Create the environment once (``python -m probaff.experiments.pusht.env``, which makes
``.venv-pusht``; or set PROBAFF_PUSHT_PYTHON). Tables and figures go to results/pusht/. Every
field of `probaff.experiments.pusht.PushTStudyConfig` is a flag (``--help`` lists them);
``probaff study pusht`` runs the same.

    python inference/pusht.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.pusht import SMOKE, Config, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    summary = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
