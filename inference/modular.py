"""Chapter 6 study: modular push, pick and place transition models against a monolithic model.

Tables and figures go to results/modular/. Every field of
`probaff.experiments.modular.ModularStudyConfig` (and of its `settings`) is a flag (``--help``
lists them); ``probaff study modular`` runs the same.

    python inference/modular.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.modular import SMOKE, Config, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    summary = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
