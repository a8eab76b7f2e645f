"""Smoke test of benchmarks/mixture_threads.py: every setting and condition, flags, bad flags."""

import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def threads(benchmark_script):
    with benchmark_script("mixture_threads") as module:
        yield module


def test_smoke_run_times_every_setting_in_both_conditions(threads, capsys):
    argv = ["--sizes", "20,40", "--max-iter", "1", "--gp-max-iter", "5", "--pool", "2"]
    assert threads.main(argv) == 0
    out = capsys.readouterr().out
    for condition in ("quiet", "loaded"):
        for n in (20, 40):
            for setting, k in (("default", 1), ("one", 1), ("pool", 2)):
                assert f"{condition:9s} | {n:5d} | {setting:7s} | {k:7d} |" in out
    assert "1 busy-loop process(es) started" in out and "/ one: wall" in out


def test_busy_loop_stops_its_processes(threads):
    with threads.busy_loop(2) as procs:
        assert len(procs) == 2 and all(p.poll() is None for p in procs)
    assert all(p.returncode is not None for p in procs)


def test_table_flags_a_default_slower_than_one_thread_beyond_noise(threads):
    def cells(default: float) -> list:
        return [
            threads.Cell("quiet", 100, "default", 1, [default, default], [default, default]),
            threads.Cell("quiet", 100, "one", 1, [1.0, 1.1], [1.0, 1.1]),
            threads.Cell("quiet", 100, "pool", 2, [9.0, 9.0], [9.0, 9.0]),
        ]

    text, flags = threads.table(cells(1.2))  # within noise
    assert flags == [] and "SLOWER" not in text
    text, flags = threads.table(cells(3.0))
    assert len(flags) == 1 and "quiet N=100" in flags[0] and "SLOWER" in text
    wall_only = cells(1.0)
    wall_only[0].wall = [3.0, 3.0]  # a slow wall clock alone is the machine, not the threads
    assert threads.table(wall_only)[1] == []


@pytest.mark.parametrize(
    ("flags", "word"),
    [
        (["--sizes", "100,-5"], "--sizes"),
        (["--sizes", "1.5"], "--sizes"),
        (["--repeats", "0"], "--repeats"),
        (["--conditions", "busy"], "busy"),
        (["--split-merge", "-1"], "--split-merge"),
        (["--pool-budget", "nan"], "--pool-budget"),
    ],
)
def test_bad_flags_exit_2_with_one_line(threads, refused_flags, flags, word):
    assert refused_flags(threads.main, flags, word).startswith("mixture_threads: error:")


def test_pool_cells_past_the_budget_are_skipped(threads, capsys):
    argv = ["--sizes", "20,40", "--max-iter", "1", "--gp-max-iter", "5", "--pool", "2"]
    assert threads.main([*argv, "--conditions", "quiet", "--pool-budget", "0.001"]) == 0
    out = capsys.readouterr().out
    assert "N=   40 pool    skipped: expected" in out
    assert "quiet     |    40 | pool    | skipped" in out and "quiet     |    20 | pool    |" in out
