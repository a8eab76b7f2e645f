"""The planning study against its stored reference of success counts: the comparison on
hand-made summaries, the reference file's bad input, and ``inference/planning.py --reference``
(the study itself replaced by a stand-in).

Covers probaff.experiments.planning.reference.
"""

import json
import runpy
import sys
from pathlib import Path

import pytest

import probaff.experiments.planning as study
from probaff.errors import InputError
from probaff.eval.metrics import wilson_interval
from probaff.experiments.planning.reference import (
    check_run,
    compare_successes,
    fell,
    load_reference,
    parse_reference,
    reference_section,
)

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "benchmarks" / "reference" / "planning.csv"
SCRIPT = ROOT / "inference" / "planning.py"

TABLE = """# a comment
part,planner,trials,successes,note
edge,astar-moe,100,96,A* with the mixture
edge,astar-gp,100,93,A* with a single GP
tool,two_step,50,39,two-step tool push
"""


def _rows(**counts):
    """Summary rows as `summarise` gives them: planner -> (successes, trials)."""
    return [{"planner": p, "successes": k, "trials": n} for p, (k, n) in counts.items()]


def _by_planner(rows):
    return {(r["part"], r["planner"]): r for r in rows}


def test_the_committed_reference_holds_the_last_full_run():
    counts = {
        (r["part"], r["planner"]): (r["successes"], r["trials"]) for r in load_reference(REFERENCE)
    }
    assert counts == {
        ("edge", "astar-moe"): (96, 100),
        ("edge", "astar-gp"): (93, 100),
        ("edge", "astar-risk-moe"): (97, 100),
        ("tool", "two_step"): (39, 50),
        ("tool", "two_step_sim"): (41, 50),
    }


def test_a_planner_whose_successes_fell_is_flagged():
    reference = parse_reference(TABLE)
    edge = _rows(**{"astar-moe": (95, 100), "astar-gp": (93, 100), "greedy-moe": (80, 100)})
    tool = _rows(two_step=(42, 50))
    rows = compare_successes(reference, edge, tool)
    by = _by_planner(rows)
    assert [(r["part"], r["planner"]) for r in rows] == [
        ("edge", "astar-moe"),
        ("edge", "astar-gp"),
        ("tool", "two_step"),
        ("edge", "greedy-moe"),
    ]
    assert by["edge", "astar-moe"]["status"] == "fell"  # one success fewer is a fall
    assert by["edge", "astar-gp"]["status"] == "same"
    assert by["tool", "two_step"]["status"] == "rose"
    assert by["edge", "greedy-moe"]["status"] == "no reference"
    assert by["edge", "greedy-moe"]["reference"] is None
    assert [r["planner"] for r in fell(rows)] == ["astar-moe"]
    moe = by["edge", "astar-moe"]
    assert (moe["reference"]["low"], moe["reference"]["high"]) == wilson_interval(96, 100)
    assert (moe["now"]["low"], moe["now"]["high"]) == wilson_interval(95, 100)
    assert moe["now"]["rate"] == 0.95 and moe["reference"]["rate"] == 0.96

    text = "\n".join(reference_section(rows, "ref.csv"))
    assert "## Against the reference ref.csv" in text
    assert "| edge | astar-moe | 96/100 = 0.96 [0.90, 0.98] | 95/100 = 0.95 [" in text
    assert "**FELL**" in text and text.count("fell below the reference") == 1
    assert "| edge | greedy-moe | - | 80/100 = 0.80" in text


def test_other_trial_counts_compare_rates_and_missing_planners_are_not_run():
    reference = parse_reference(TABLE)
    # a smoke-sized run: 2 episodes of one planner, 1 trial of the tool push
    rows = compare_successes(reference, _rows(**{"astar-moe": (2, 2)}), _rows(two_step=(0, 1)))
    by = _by_planner(rows)
    assert by["edge", "astar-moe"]["status"] == "rose"  # 2/2 above 96/100
    assert by["tool", "two_step"]["status"] == "fell"  # 0/1 below 39/50
    assert by["edge", "astar-gp"]["status"] == "not run" and by["edge", "astar-gp"]["now"] is None
    assert compare_successes(reference, _rows(**{"astar-moe": (48, 50)}))[0]["status"] == "same"
    assert all(r["status"] == "not run" for r in compare_successes(reference))
    with pytest.raises(InputError, match=r"edge_rows\[0\] lacks planner, trials or successes"):
        compare_successes(reference, [{"planner": "astar-moe", "trials": 3}])


MALFORMED = {
    "unknown edge planner": (
        "part,planner,trials,successes\nedge,astar-lstm,100,96\n",
        r"row 1: unknown edge planner 'astar-lstm'; choose from \['astar-moe'",
    ),
    "tool planner under edge": (
        "part,planner,trials,successes\nedge,two_step,50,39\n",
        "unknown edge planner 'two_step'",
    ),
    "unknown part": ("part,planner,trials,successes\nwalk,astar-moe,1,1\n", "unknown part 'walk'"),
    "columns": ("planner,successes\nastar-moe,96\n", "its columns are"),
    "no header": ("", "its columns are"),
    "text count": ("part,planner,trials,successes\nedge,astar-moe,100,many\n", "successes must"),
    "negative": ("part,planner,trials,successes\nedge,astar-moe,-1,0\n", "trials must be"),
    "zero trials": ("part,planner,trials,successes\nedge,astar-moe,0,0\n", "1 <= trials"),
    "too many": ("part,planner,trials,successes\nedge,astar-moe,10,11\n", "successes <= trials"),
    "short row": ("part,planner,trials,successes\nedge,astar-moe,100\n", "expected the cells"),
    "repeated": (
        "part,planner,trials,successes\nedge,astar-moe,100,96\nedge,astar-moe,100,95\n",
        "row 2: edge planner 'astar-moe' repeats",
    ),
    "no rows": ("# only a comment\npart,planner,trials,successes\n", "holds no planners"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_a_malformed_reference_is_refused(case):
    text, message = MALFORMED[case]
    with pytest.raises(InputError, match=message):
        parse_reference(text, "--reference r.csv")


def test_a_missing_or_unreadable_reference_is_refused(tmp_path):
    with pytest.raises(InputError, match=r"--reference .*nope.csv does not exist"):
        load_reference(tmp_path / "nope.csv")
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match="cannot be read"):
        load_reference(tmp_path / "binary.csv")
    with pytest.raises(InputError, match="cannot be read"):
        load_reference(tmp_path)


def test_check_run_writes_the_comparison(tmp_path):
    summary = {"edge": _rows(**{"astar-moe": (90, 100)}), "tool": [], "files": []}
    rows, lines, path = check_run(parse_reference(TABLE), summary, tmp_path / "out", "r.csv")
    assert path == str(tmp_path / "out" / "reference_check.md")
    assert Path(path).read_text() == "\n".join(lines)
    assert [r["planner"] for r in fell(rows)] == ["astar-moe"]


# --- inference/planning.py --reference, with the study replaced by a stand-in


@pytest.fixture
def fake_study(monkeypatch):
    """Replace the study's `run` by a stand-in that returns the given summary rows."""
    calls = []

    def use(edge, tool):
        def fake_run(config):
            calls.append(config)
            return {"edge": edge, "tool": tool, "files": [f"{config.out}/summary.md"]}

        monkeypatch.setattr(study, "run", fake_run)
        return calls

    return use


def _script(monkeypatch, capsys, *args):
    monkeypatch.setattr(sys, "argv", [str(SCRIPT), *args])
    with pytest.raises(SystemExit) as info:
        runpy.run_path(str(SCRIPT), run_name="__main__")
    out, err = capsys.readouterr()
    return info.value.code, out, err


def test_script_exits_1_when_a_planner_fell(monkeypatch, capsys, tmp_path, fake_study):
    edge = _rows(**{"astar-moe": (96, 100), "astar-gp": (92, 100), "astar-risk-moe": (97, 100)})
    tool = _rows(two_step=(39, 50), two_step_sim=(41, 50))
    calls = fake_study(edge, tool)
    out = tmp_path / "out"
    code, stdout, stderr = _script(
        monkeypatch, capsys, "--reference", str(REFERENCE), "--out", str(out)
    )
    assert code == 1 and len(calls) == 1
    assert json.loads(stdout)["files"][-1] == str(out / "reference_check.md")
    assert "edge planner astar-gp fell below the reference: 92/100" in stderr
    assert stderr.count("**FELL**") == 1

    fake_study([*edge[:1], {"planner": "astar-gp", "successes": 93, "trials": 100}, edge[2]], tool)
    code, stdout, stderr = _script(
        monkeypatch, capsys, "--reference", str(REFERENCE), "--out", str(out)
    )
    assert code == 0 and "FELL" not in stderr and "| tool | two_step_sim | 41/50" in stderr


def test_script_refuses_a_bad_reference_before_any_work(monkeypatch, capsys, tmp_path, fake_study):
    calls = fake_study([], [])
    bad = tmp_path / "bad.csv"
    bad.write_text("part,planner,trials,successes\nedge,astar-lstm,100,96\n")
    for path, message in ((tmp_path / "nope.csv", "does not exist"), (bad, "astar-lstm")):
        code, stdout, stderr = _script(monkeypatch, capsys, "--reference", str(path), "--smoke")
        assert code == 2 and stdout == ""
        assert len(stderr.strip().splitlines()) == 1
        assert f"--reference {path}" in stderr and message in stderr
    assert calls == []
    # without --reference the script runs as before
    code, stdout, _ = _script(monkeypatch, capsys, "--smoke", "--out", str(tmp_path / "o"))
    assert code == 0 and json.loads(stdout) == {"files": [f"{tmp_path / 'o'}/summary.md"]}


def test_script_refuses_a_reference_with_another_replanning_distance(
    monkeypatch, capsys, tmp_path, fake_study
):
    calls = fake_study([], [])
    args = ("--reference", str(REFERENCE), "--replan-distance", "0.02", "--out", str(tmp_path))
    code, stdout, stderr = _script(monkeypatch, capsys, *args)
    assert code == 2 and calls == [] and stdout == ""
    assert "drop --replan-distance" in stderr and len(stderr.strip().splitlines()) == 1
