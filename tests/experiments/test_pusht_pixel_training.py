"""Push-T training pushes recorded from pixels: perceived poses only, the state for scoring.

Covers probaff.experiments.pusht.data (``record_pushes``/``record_chunk`` with
``observation="pixels"``, ``push_dataset``, ``perception_errors``, ``dataset_observation``),
``PixelObserver.look`` (probaff.experiments.pusht.observe), the study's keys of pixel runs
(probaff.experiments.pusht.run) and the refusal to plan from one observation with a model
fitted on pushes recorded from the other
(probaff.experiments.pusht.models.check_model_observation, ``run_episode``). Mirrors the
evaluation-side test (test_pusht_perception.py, the planner never handed the state): with the
worker's state made useless, the recorded dataset is the same.
"""

import base64
import importlib

import numpy as np
import pytest
from study_helpers import BlankPushTWorker, PoisonedPushTWorker

from probaff.errors import InputError, ProbaffError
from probaff.experiments.pusht.data import (
    chunk_rng,
    dataset_observation,
    perception_errors,
    push_dataset,
    record_chunk,
    record_pushes,
)
from probaff.experiments.pusht.env import PushTEnvError, PushTWorker
from probaff.experiments.pusht.models import (
    FEATURES,
    LearnedModel,
    ObservationMismatchError,
    QuasiStaticTee,
    check_model_observation,
    push_effects,
    push_features,
)
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.transitions import ModelTransition

N = 4
PERCEIVED = ("before", "after", "origin", "yaw", "dist", "approach_moved", "shape")


@pytest.fixture(scope="module")
def recorded(pusht_python):
    """The same seeded chunk recorded from pixels by a clean and by a poisoned worker."""
    s = PrimitiveSettings()
    out = {}
    w = PushTWorker(pusht_python)
    try:
        for poison in (False, True):
            proxy = PoisonedPushTWorker(w) if poison else w
            out[poison] = record_pushes(proxy, chunk_rng(5, "train", 0), N, s, observation="pixels")
    finally:
        w.close()
    return out


@pytest.mark.slow
def test_pixel_recorded_pushes_never_read_the_state(recorded):
    clean, poisoned = recorded[False], recorded[True]
    for key in PERCEIVED:  # with the state made useless, the same pushes, to the bit
        assert np.array_equal(np.asarray(clean[key]), np.asarray(poisoned[key])), key
        assert np.all(np.isfinite(np.asarray(poisoned[key], dtype=float))), key
    assert len(clean["before"]) == N
    # the state is logged beside, for scoring only; the poisoned run has none to log
    assert np.all(np.isfinite(clean["truth_before"])) and np.all(np.isnan(poisoned["truth_after"]))
    a, b = push_dataset([clean], 5), push_dataset([poisoned], 5)
    assert np.array_equal(push_features(a), push_features(b))
    assert np.array_equal(push_effects(a), push_effects(b))
    assert a.meta["observation"] == "pixels" and a.meta["poses"] == "perceived"
    assert dataset_observation(a) == "pixels" and a.observation_only
    assert set(a.meta["perception"]) == {
        "lost_resets",
        "dropped_start",
        "dropped_end",
        "flagged",
        "retreats",
    }
    # the perceived poses are near the state's, not the state's
    assert not np.array_equal(clean["before"], clean["truth_before"])
    errors = perception_errors([clean])
    assert errors["pose_px"].shape == (2 * N,) and errors["effect_z"].shape == (N,)
    assert np.median(errors["pose_px"]) < 0.5 and np.median(errors["pose_deg"]) < 1.0
    with pytest.raises(InputError, match="nothing to score"):  # and does not pretend to
        perception_errors([poisoned])
    # the dataset of the logged state is for scoring, and says so
    truth = push_dataset([clean], 5, truth=True)
    assert truth.meta["poses"] == "state_beside_perceived"


def test_state_and_pixel_chunks_are_told_apart(recorded, pusht_python):
    state = record_chunk("train", 0, 5, 3, settings=PrimitiveSettings(), python=pusht_python)
    ds = push_dataset([state], 5)
    assert dataset_observation(ds) == "state" and ds.meta["poses"] == "state"
    with pytest.raises(InputError, match="mix"):
        push_dataset([state, recorded[False]], 5)
    with pytest.raises(InputError, match="truth=True"):
        push_dataset([state], 5, truth=True)
    with pytest.raises(InputError, match="records"):
        push_dataset([], 5)
    with pytest.raises(InputError, match="record_chunk"):
        perception_errors([state])


def test_bad_observation_is_refused_before_the_worker_is_asked():
    with pytest.raises(InputError, match="observation must be one of"):
        record_pushes(None, chunk_rng(0, "train", 0), 1, PrimitiveSettings(), observation="cam")
    with pytest.raises(InputError, match="observation"):
        record_chunk("train", 0, 0, 1, settings=PrimitiveSettings(), python=None, observation=3)


class _ReachedError(Exception):
    """Raised by `_Unreachable`: the episode got past its checks."""


class _Unreachable:
    def ask(self, cmd, **fields):
        raise _ReachedError(cmd)


def test_a_model_of_the_other_observation_is_refused_unless_allowed():
    from probaff.experiments.pusht.planner import SearchSettings, run_episode

    prims, search = PrimitiveSettings(), SearchSettings(candidates=4, beam=1, children=1)
    state_moe = ModelTransition(LearnedModel("moe", object()))  # fitted before: state
    pixel_moe = ModelTransition(LearnedModel("moe", object(), FEATURES, "pixels"))
    for transition, observation in ((state_moe, "pixels"), (pixel_moe, "state")):
        with pytest.raises(ObservationMismatchError) as info:
            run_episode(_Unreachable(), 0, transition, search, prims, observation=observation)
        text = str(info.value)
        assert f"observation={observation!r}" in text and "allow_observation_mismatch" in text
        assert isinstance(info.value, InputError) and isinstance(info.value, ProbaffError)
        with pytest.raises(_ReachedError):  # allowed: the episode starts
            run_episode(
                _Unreachable(),
                0,
                transition,
                search,
                prims,
                observation=observation,
                allow_observation_mismatch=True,
            )
    for transition, observation in ((state_moe, "state"), (pixel_moe, "pixels")):
        with pytest.raises(_ReachedError):  # matched: the episode starts
            run_episode(_Unreachable(), 0, transition, search, prims, observation=observation)
    # a hand-set analytic model was fitted on no pushes: it plans from either
    check_model_observation(ModelTransition(QuasiStaticTee(sigma=np.ones(3))), "pixels")
    calibrated = QuasiStaticTee(sigma=np.ones(3), observation="state")
    with pytest.raises(ObservationMismatchError, match="analytic"):
        check_model_observation(ModelTransition(calibrated), "pixels")


def test_pixel_runs_are_keyed_apart_from_state_runs(recorded, tmp_path):
    from probaff.experiments.base import StudyRun
    from probaff.experiments.pusht import PushTStudyConfig

    study = importlib.import_module("probaff.experiments.pusht.run")  # the module, not `run`

    state = PushTStudyConfig(out=str(tmp_path / "s"))
    pixels = PushTStudyConfig(out=str(tmp_path / "p"), observation="pixels")
    for fields in (study._DATA_FIELDS, study._MODEL_FIELDS):
        # state runs keep the keys they had; pixel runs get their own
        assert study._observed(state, fields) == fields
        assert state.tag(only=study._observed(state, fields), version=1) == state.tag(
            only=fields, version=1
        )
        assert pixels.tag(only=study._observed(pixels, fields), version=1) != state.tag(
            only=study._observed(state, fields), version=1
        )
    ds = push_dataset([recorded[False]], 5)
    models = study._models(StudyRun(pixels), ds, N, {"analytic"})
    assert models["analytic"].observation == "pixels"


def test_episodes_that_never_show_the_t_are_reset_then_given_up(monkeypatch):
    from probaff.experiments.pusht import data

    monkeypatch.setattr(data, "_MAX_LOST_RESETS", 2)  # 20 by default; each reset looks 4 times
    blank = BlankPushTWorker()
    with pytest.raises(PushTEnvError, match="2 resets in a row"):
        record_pushes(blank, chunk_rng(0, "train", 0), 1, PrimitiveSettings(), observation="pixels")
    assert blank.resets == 2  # each one looked at again after backing away, never planned on


class _Hiding:
    """A worker whose camera shows an empty floor in the last frame of the step calls `hide`
    (counted from 1 over every step call: a push's approach, its push, a retreat, ...)."""

    def __init__(self, worker, hide: set[int]) -> None:
        self.worker, self.hide, self.calls = worker, hide, 0
        self.blank = base64.b64encode(np.full((96, 96, 3), 255, np.uint8).tobytes()).decode()

    def ask(self, cmd, **fields):
        answer = self.worker.ask(cmd, **fields)
        if cmd == "step":
            self.calls += 1
            if self.calls in self.hide and answer["pixels"]:
                answer["pixels"][-1] = self.blank
        return answer


def test_unreadable_frames_drop_the_push_or_are_looked_at_again(pusht_python):
    w = PushTWorker(pusht_python)
    try:
        # calls 1, 2: the first push's approach (its start unreadable) and push; 3, 4: the
        # second push's approach and push (its end unreadable: the pusher backs away, call 5)
        proxy = _Hiding(w, {1, 4})
        rows = record_pushes(proxy, chunk_rng(5, "train", 0), 2, PrimitiveSettings(),
                             observation="pixels")  # fmt: skip
    finally:
        w.close()
    counts = rows["perception"]
    assert counts["dropped_start"] == 1 and counts["dropped_end"] == 0
    assert counts["retreats"] == 1 and counts["flagged"] == 2
    assert len(rows["before"]) == 2 and np.all(np.isfinite(rows["after"]))
    ds = push_dataset([rows], 5)
    assert ds.meta["perception"]["dropped_start"] == 1 and len(ds) == 2
