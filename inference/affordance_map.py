"""Affordance-map study (thesis chapter 3): information-gain pushing against exhaustive pushing.

Tables and figures (Figs. 3.5-3.7) go to results/affordance_map/. Every field of
`probaff.experiments.affordance_map.AffordanceMapConfig` (and of its `MRFParams`) is a flag
(``--help`` lists them); ``probaff study affordance_map`` runs the same.

    python inference/affordance_map.py [--n-maps N] [--workers K | --scheduler ADDR] [--smoke]
"""

import sys

from probaff.experiments.affordance_map import SMOKE, Config, run
from probaff.experiments.config_cli import run_study_script

if __name__ == "__main__":
    sys.exit(run_study_script(Config, SMOKE, run, __doc__, shown=("files", "computed")))
