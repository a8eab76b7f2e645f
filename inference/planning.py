"""Planning study (thesis chapters 4 and 5): push-to-edge and tool-push planners, closed loop.

Tables and figures go to results/planning/. Every field of
`probaff.experiments.planning.PlanningStudyConfig` is a flag (``--help`` lists them);
``probaff study planning`` runs the same (without ``--reference``).

    python inference/planning.py [--workers K | --scheduler ADDR] [--smoke] [--FIELD VALUE]
        [--reference benchmarks/reference/planning.csv]

``--reference FILE`` (read before any work) sets each planner's successes beside the file's
(`probaff.experiments.planning.reference`), writes the table to ``out/reference_check.md``,
prints it on stderr and exits with status 1 if a planner's success count fell below it.
"""

import json
import sys

from probaff._cli_errors import run_cli
from probaff.errors import InputError
from probaff.experiments.config_cli import study_config, study_parser
from probaff.experiments.planning import SMOKE, Config, run
from probaff.experiments.planning.reference import check_run, fell, load_reference


def main() -> int:
    """Parse the command line into a study config, run it, and check it against a reference."""
    parser = study_parser(Config, __doc__)
    parser.add_argument(
        "--reference",
        metavar="FILE",
        help="compare each planner's successes with this table of success counts "
        "(benchmarks/reference/planning.csv); exit status 1 if one fell below it",
    )
    args = parser.parse_args()
    reference = None if args.reference is None else load_reference(args.reference)
    config = study_config(Config, args, SMOKE)
    if reference is not None and config.replan_distance is not None:
        raise InputError(
            "--reference holds successes measured with the task file's replanning distance "
            "(5 cm, the thesis's rule); drop --replan-distance to check a run against it."
        )
    summary = run(config)
    status = 0
    if reference is not None:
        rows, lines, path = check_run(reference, summary, config.out, args.reference)
        summary["files"].append(path)
        print("\n".join(lines), file=sys.stderr)
        status = 1 if fell(rows) else 0
    print(json.dumps({"files": summary["files"]}, indent=1))
    return status


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad flag: one line on stderr, exit status 2
