"""Chapter 2 study: affordance labels of scanned office segments, Algorithm 1, multi-view merge.

Tables and figures go to results/point_cloud_labels/. Every field of
`probaff.studies.point_cloud_labels.PointCloudStudyConfig` (and of its `perception`) is a flag
(``--help`` lists them).

    python inference/point_cloud_labels.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD V]
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.studies.config_cli import study_config, study_parser
from probaff.studies.point_cloud_labels import SMOKE_OVERRIDES, PointCloudStudyConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    args = study_parser(PointCloudStudyConfig, __doc__).parse_args()
    summary = run(study_config(PointCloudStudyConfig, args, SMOKE_OVERRIDES))
    print(json.dumps({"files": summary["files"]}, indent=1))


if __name__ == "__main__":
    sys.exit(run_cli(main))
