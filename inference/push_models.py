"""Push-model study (thesis chapters 5 and 4): EM and VI mixtures of GP experts.

Cross-validated tables and figures go to results/push_models/. Every field of
`probaff.experiments.push_models.PushModelStudyConfig` is a flag (``--help`` lists them);
``probaff study push_models`` runs the same.

    python inference/push_models.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import sys

from probaff.experiments.config_cli import run_study_script
from probaff.experiments.push_models import SMOKE, Config, run

if __name__ == "__main__":
    sys.exit(run_study_script(Config, SMOKE, run, __doc__))
