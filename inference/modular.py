"""Chapter 6 study: modular push, pick and place transition models against a monolithic model.

Tables and figures go to results/modular/. Every field of
`probaff.studies.modular.ModularStudyConfig` (and of its `settings`) is a flag (``--help``
lists them).

    python inference/modular.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import study_config, study_parser
from probaff.studies.modular import SMOKE_OVERRIDES, ModularStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    args = study_parser(ModularStudyConfig, __doc__).parse_args()
    summary = run(study_config(ModularStudyConfig, args, SMOKE_OVERRIDES))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
