"""Chapter 6 study: modular push, pick and place transition models against a monolithic model.

Tables and figures go to results/modular/. Every field of
`probaff.studies.modular.ModularStudyConfig` (and of its `settings`) is a flag (``--help``
lists them).

    python inference/modular.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import argparse
import dataclasses
import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import add_config_arguments, config_from_args
from probaff.studies.modular import SMOKE_OVERRIDES, ModularStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(p, ModularStudyConfig)
    p.add_argument(
        "--smoke",
        action="store_true",
        help="a tiny run that checks the pipeline (sizes from SMOKE_OVERRIDES; "
        "the other flags still apply)",
    )
    a = p.parse_args()
    cfg = config_from_args(ModularStudyConfig, a)
    if a.smoke:
        cfg = dataclasses.replace(cfg, **SMOKE_OVERRIDES)
    summary = run(cfg)
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
