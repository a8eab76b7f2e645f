"""Push-T study: learned push models and a planner in the unmodified gym-pusht environment.

Create the environment once (``python -m probaff.experiments.pusht.env``, which makes
``.venv-pusht``; or set PROBAFF_PUSHT_PYTHON). Tables and figures go to results/pusht/. Every
field of `probaff.experiments.pusht.PushTStudyConfig` is a flag (``--help`` lists them);
``probaff study pusht`` runs the same.

    python inference/pusht.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import sys

from probaff.experiments.config_cli import run_study_script
from probaff.experiments.pusht import SMOKE, Config, run

if __name__ == "__main__":
    sys.exit(run_study_script(Config, SMOKE, run, __doc__))
