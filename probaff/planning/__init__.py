"""Acting on what was learned: affordance maps (chapter 3) and push planners (chapters 4, 5).

`probaff.maps` is the factor-graph library (the MRF, its inference and entropies) and
`probaff.models` the push models; this package is the robot built on them. What a planner
scores is apart from how it searches:

- what is scored: one transition protocol (`Transition`: where N candidate pushes leave K
  objects), with learned, simulator and analytic implementations (`transitions`), over a
  fitted push model joined to its features (`learned`); a task with pushes of its own asks it
  with its own batch (Push-T: `probaff.experiments.pusht.transitions`);
- how it is searched: A*, the greedy one step and sampling in two steps, whatever the task
  (`search`; Push-T's planner, `probaff.experiments.pusht.planner`, samples on it too);
- the tasks, each in its own subpackage: `push_to_edge` (chapter 4: push a book over the
  table edge; A* and greedy planners, closed-loop episodes), `tool_push` (chapter 5: push a
  tool into a target to bring it within reach; two-step planner, trials) and `manipulation`
  (chapter 3: the manipulation loop on an affordance map, change detection, information
  gain, the affordance classifier);
- the catalogue of planners and their models (`catalogue`).

Modules:
    transitions: the transition protocol, its prediction and checks, and its learned,
        simulator and quasi-static implementations.
    learned: a fitted push model with the features it reads (`FeaturePushModel`), and
        pushing-frame effects back to world poses (`apply_effects`).
    search: A*, greedy and sampling searches over a task's states.
    geometry: rectangular footprints (corners, overlaps, chords).
    catalogue: the push-to-edge planners and models, and the tool push's model fit.
    push_to_edge, tool_push, manipulation: the tasks.

The planning study is `probaff.experiments.planning`.
"""

from probaff.planning.catalogue import (
    EDGE_MODELS,
    EDGE_PLANNERS,
    edge_transition,
    fit_edge_model,
    fit_tool_push_model,
)
from probaff.planning.learned import FeaturePushModel
from probaff.planning.manipulation.classifier import AffordanceClassifier, collect_voxels
from probaff.planning.manipulation.info_gain import plan_pushes
from probaff.planning.manipulation.loop import POLICIES, ManipulationLoop, plan_pushes_on_grid
from probaff.planning.push_to_edge.episode import run_edge_episode
from probaff.planning.push_to_edge.planners import PushReachability, plan_astar, plan_greedy
from probaff.planning.push_to_edge.task import EdgeTask, load_edge_task, sample_episode
from probaff.planning.search import astar, greedy, sample_two_steps
from probaff.planning.tool_push.config import ToolPushConfig
from probaff.planning.tool_push.planners import plan_random_push, plan_single_push, plan_tool_push
from probaff.planning.tool_push.state import ToolPushState
from probaff.planning.tool_push.trials import TOOL_PUSH_PLANNERS, run_tool_push_trial
from probaff.planning.transitions import (
    LearnedTransition,
    QuasiStaticTransition,
    SimulatorTransition,
    Transition,
    TransitionPrediction,
)

__all__ = [
    "EDGE_MODELS",
    "EDGE_PLANNERS",
    "POLICIES",
    "TOOL_PUSH_PLANNERS",
    "AffordanceClassifier",
    "EdgeTask",
    "FeaturePushModel",
    "LearnedTransition",
    "ManipulationLoop",
    "PushReachability",
    "QuasiStaticTransition",
    "SimulatorTransition",
    "ToolPushConfig",
    "ToolPushState",
    "Transition",
    "TransitionPrediction",
    "astar",
    "collect_voxels",
    "edge_transition",
    "fit_edge_model",
    "fit_tool_push_model",
    "greedy",
    "load_edge_task",
    "plan_astar",
    "plan_greedy",
    "plan_pushes",
    "plan_pushes_on_grid",
    "plan_random_push",
    "plan_single_push",
    "plan_tool_push",
    "run_edge_episode",
    "run_tool_push_trial",
    "sample_episode",
    "sample_two_steps",
]
