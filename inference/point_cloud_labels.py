"""Chapter 2 study: affordance labels of scanned office segments, Algorithm 1, multi-view merge.

Tables and figures go to results/point_cloud_labels/. Every field of
`probaff.experiments.point_cloud_labels.PointCloudStudyConfig` (and of its `perception`) is
a flag (``--help`` lists them); ``probaff study point_cloud_labels`` runs the same.

    python inference/point_cloud_labels.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD V]
"""

import sys

from probaff.experiments.config_cli import run_study_script
from probaff.experiments.point_cloud_labels import SMOKE, Config, run

if __name__ == "__main__":
    sys.exit(run_study_script(Config, SMOKE, run, __doc__))
