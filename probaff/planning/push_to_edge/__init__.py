"""Chapter 4's push-to-edge task: push a book over the table edge until it can be grasped.

Modules:
    task: the task's geometry (goal, falls, collisions), its candidate pushes, its YAML loader
        and episode starts.
    planners: the book and the battery as a transition's state (`predict_books`), the arm's
        push reachability, and the A* and greedy planners over book poses.
    episode: one closed-loop episode in the simulator, with replanning.
"""

from probaff.planning.push_to_edge.episode import (
    EDGE_SEARCHES,
    EdgeEpisode,
    EdgeStep,
    run_edge_episode,
)
from probaff.planning.push_to_edge.planners import (
    EdgePlan,
    EdgePlanner,
    PushReachability,
    plan_astar,
    plan_greedy,
    predict_books,
    push_admissible,
)
from probaff.planning.push_to_edge.task import (
    EdgeTask,
    RiskBounds,
    SearchOptions,
    load_edge_task,
    sample_episode,
)

__all__ = [
    "EDGE_SEARCHES",
    "EdgeEpisode",
    "EdgePlan",
    "EdgePlanner",
    "EdgeStep",
    "EdgeTask",
    "PushReachability",
    "RiskBounds",
    "SearchOptions",
    "load_edge_task",
    "plan_astar",
    "plan_greedy",
    "predict_books",
    "push_admissible",
    "run_edge_episode",
    "sample_episode",
]
