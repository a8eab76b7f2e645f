"""Chapter 6 study: modular push, pick and place transition models against a monolithic model.

Tables and figures go to results/modular/. Every field of
`probaff.experiments.modular.ModularStudyConfig` (and of its `settings`) is a flag (``--help``
lists them); ``probaff study modular`` runs the same.

    python inference/modular.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
"""

import sys

from probaff.experiments.config_cli import run_study_script
from probaff.experiments.modular import SMOKE, Config, run

if __name__ == "__main__":
    sys.exit(run_study_script(Config, SMOKE, run, __doc__))
