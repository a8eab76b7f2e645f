"""Chapter 2 study: affordance labels of scanned office segments, Algorithm 1, multi-view merge.

Tables and figures go to results/point_cloud_labels/. Every field of
`probaff.experiments.point_cloud_labels.PointCloudStudyConfig` (and of its `perception`) is
a flag (``--help`` lists them); ``probaff study point_cloud_labels`` runs the same.

    python inference/point_cloud_labels.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD V]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.experiments.config_cli import parse_study_args
from probaff.experiments.point_cloud_labels import SMOKE, Config, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    summary = run(parse_study_args(Config, SMOKE, __doc__))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
