"""The Push-T study: learn push models in the unmodified gym-pusht environment, then plan.

gym-pusht runs in its own virtual environment (``python -m probaff.experiments.pusht.env``
creates ``.venv-pusht``), behind a worker process that probaff speaks JSON lines with.

Modules:
    config: `PushTStudyConfig`, the planners, the diffusion policy's result, the smoke sizes.
    env: creating the Push-T environment, and `PushTWorker`, the process that runs it.
    geometry: the T (gym-pusht's, or one perceived), its frames, distances and the vertex cost.
    perception: the goal, the T's outline and the block's pose read off the diffusion
        policy's 96 x 96 image, with an uncertainty and a flag for frames it cannot read.
    observe: what the planner observes, the state or only the image and the agent's position.
    primitives: push primitives (contact, direction, length) as agent targets.
    data: random pushes recorded as an observation-only probaff push dataset.
    active: training pushes chosen by the model's predictive variance, or at random.
    models: features, the mixture and the single GP, the analytic quasi-static model.
    transitions: a model or the environment as a `probaff.planning` transition of the T.
    planner: the push search on `probaff.planning.search`, closed-loop episodes.
    run: the pushes, fits and episodes as resumable tasks, and `run`.
    scoring: success with its interval and the environment's own reward, as LeRobot scores.
    report: the tables in those units, model scores, blame, the summary.
    figures: episodes over the goal, success and model scores against training pushes.
"""

from probaff.experiments.pusht.config import PLANNERS, SMOKE, PushTStudyConfig
from probaff.experiments.pusht.run import run

Config = PushTStudyConfig
"""The study's config class (the registry's name for it)."""

__all__ = ["PLANNERS", "SMOKE", "Config", "PushTStudyConfig", "run"]
