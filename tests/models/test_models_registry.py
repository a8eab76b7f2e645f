"""The model registry: built-in kinds, dispatch, building, and a new kind added in this file.

Adding a kind of model is its module (here, the `ConstantGaussian` below), one
`register_model_kind` call, and a test: the new kind is then fitted by `fit`, built from
`ModelSettings`, and saved and loaded by `probaff.models.save` / `load` like any other.
"""

from dataclasses import dataclass
from typing import Any

import pytest
import torch
from torch.distributions import Independent, Normal

import probaff.models as models
from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models import (
    MIXTURE_GP,
    ClusteredGPModel,
    EMOptions,
    GPOptions,
    MixtureOfGPExperts,
    ModelKind,
    ModelSettings,
    MonolithicTransitionModel,
    PushModel,
    SkillTransitionModel,
    SVIOptions,
    VariationalMixtureOfGPExperts,
    fit,
    fit_em,
    load,
    model_kind,
    model_kinds,
    register_model_kind,
    save,
    unregister_model_kind,
)
from probaff.models.options import resolve_options
from probaff.models.persistence import FORMATS
from probaff.models.registry import Codec


# ------------------------------------------------------------- a new kind
@dataclass(frozen=True)
class ConstantOptions:
    """Fitting options of `ConstantGaussian`: how many of the first rows to fit on."""

    rows: int | None = None

    def __post_init__(self) -> None:
        if self.rows is not None:
            object.__setattr__(self, "rows", check_count("rows", self.rows))


class ConstantGaussian:
    """Predicts the same independent Gaussian over effects for every input."""

    def __init__(self, floor: float = 1e-3) -> None:
        self.floor = float(floor)
        self.mean: torch.Tensor | None = None
        self.std: torch.Tensor | None = None

    @property
    def n_outputs(self) -> int | None:
        return None if self.mean is None else int(self.mean.shape[0])

    def check_fitted(self) -> None:
        if self.mean is None:
            raise NotFittedError("ConstantGaussian is not fitted.")

    def predict(self, X: Any) -> Independent:
        self.check_fitted()
        assert self.mean is not None and self.std is not None
        n = torch.as_tensor(X).shape[0]
        return Independent(Normal(self.mean.expand(n, -1), self.std.expand(n, -1)), 1)


def fit_constant(
    model: ConstantGaussian, X: Any, Y: Any, options: ConstantOptions | None = None, **kw: Any
) -> ConstantGaussian:
    opts = resolve_options(ConstantOptions, options, kw)
    y = torch.as_tensor(Y, dtype=torch.float64)[: opts.rows]
    model.mean, model.std = y.mean(0), y.std(0, correction=0).clamp_min(model.floor)
    return model


def _restore_constant(payload: dict[str, Any]) -> ConstantGaussian:
    model = ConstantGaussian(payload["floor"])
    model.mean, model.std = payload["mean"], payload["std"]
    return model


def _new_kind() -> ModelKind:
    return ModelKind(
        "constant",
        ConstantGaussian,
        fit_constant,
        ConstantOptions,
        codec=Codec(
            "tests.ConstantGaussian/1",
            lambda m: {"floor": m.floor, "mean": m.mean, "std": m.std},
            _restore_constant,
            ("floor", "mean", "std"),
        ),
        builder=lambda s: ConstantGaussian(),
    )


@pytest.fixture
def constant_kind():
    kind = register_model_kind(_new_kind())
    try:
        yield kind
    finally:
        unregister_model_kind("constant")


def _data(n=30):
    g = torch.Generator().manual_seed(0)
    x = torch.rand(n, 2, generator=g, dtype=torch.float64)
    y = torch.cat([x[:, :1] * 2.0, -x[:, 1:]], dim=1)
    return x, y


def test_a_new_kind_is_fitted_built_saved_and_loaded(constant_kind, tmp_path):
    x, y = _data()
    model = ConstantGaussian()
    assert model_kind(model) is constant_kind and model_kind("constant") is constant_kind
    assert fit(model, x, y, ConstantOptions(rows=10)) is model
    assert torch.equal(model.mean, y[:10].mean(0))
    fit(model, x, y, rows=20)
    assert torch.equal(model.mean, y[:20].mean(0))
    assert isinstance(model, PushModel)
    assert model_kind("constant").fit is fit_constant and "constant" in model_kinds()
    assert FORMATS[ConstantGaussian] == "tests.ConstantGaussian/1"
    save(model, tmp_path / "constant.pt")
    loaded = load(tmp_path / "constant.pt")
    assert isinstance(loaded, ConstantGaussian)
    assert torch.equal(loaded.predict(x).mean, model.predict(x).mean)
    built = constant_kind.fit_new(x, y, fit={"rows": 5})
    assert torch.equal(built.mean, y[:5].mean(0))
    assert constant_kind.option_names == {"rows"}


def test_unregistered_kinds_are_gone(constant_kind, tmp_path):
    save(fit(ConstantGaussian(), *_data()), tmp_path / "c.pt")
    unregister_model_kind("constant")
    try:
        with pytest.raises(InputError, match="not a registered kind"):
            fit(ConstantGaussian(), *_data())
        with pytest.raises(InputError, match="cannot save a ConstantGaussian"):
            save(ConstantGaussian(), tmp_path / "d.pt")
        with pytest.raises(InputError, match="not a saved mixture or model of a known format"):
            load(tmp_path / "c.pt")
    finally:
        register_model_kind(_new_kind())


# ------------------------------------------------------------ built-in kinds
def test_builtin_kinds():
    kinds = model_kinds()
    assert {"em", "svi", "clustered", "transition", "monolithic"} <= set(kinds)
    assert kinds["em"].model_class is MixtureOfGPExperts and kinds["em"].fit is fit_em
    assert kinds["em"].options_type is EMOptions and kinds["svi"].options_type is SVIOptions
    assert kinds["transition"].options_type is EMOptions
    assert kinds["clustered"].options_type is None and kinds["monolithic"].option_names == set()
    for name, cls in [
        ("em", MixtureOfGPExperts),
        ("svi", VariationalMixtureOfGPExperts),
        ("clustered", ClusteredGPModel),
        ("transition", SkillTransitionModel),
        ("monolithic", MonolithicTransitionModel),
    ]:
        assert kinds[name].model_class is cls
        assert kinds[name].codec.format == f"probaff.models.{cls.__name__}/1"
        assert FORMATS[cls] == kinds[name].codec.format


def test_a_subclass_is_its_parents_kind():
    class Mine(MixtureOfGPExperts):
        pass

    assert model_kind(Mine(2)).name == "em"


def test_registration_refuses_clashes_and_bad_kinds():
    with pytest.raises(InputError, match="already the class of model kind 'em'"):
        register_model_kind(ModelKind("em2", MixtureOfGPExperts, fit_em))
    with pytest.raises(InputError, match="already model kind 'em'"):
        register_model_kind(
            ModelKind(
                "em2",
                ConstantGaussian,
                fit_constant,
                codec=Codec(model_kind("em").codec.format, dict, dict),
            )
        )
    with pytest.raises(InputError, match="must be a Codec"):
        ModelKind("x", ConstantGaussian, fit_constant, codec="x/1")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="non-empty"):
        Codec("", dict, dict)
    with pytest.raises(InputError, match="non-empty"):
        ModelKind("", ConstantGaussian, fit_constant)
    with pytest.raises(InputError, match="takes a ModelKind"):
        register_model_kind("em")  # type: ignore[arg-type]
    with pytest.raises(
        InputError, match="model kind 'em' is registered already; unregister_model_kind"
    ):
        register_model_kind(ModelKind("em", ConstantGaussian, fit_constant))
    with pytest.raises(InputError, match="model kind 'nope' is not registered"):
        unregister_model_kind("nope")
    with pytest.raises(
        InputError, match=r"unknown model kind 'nope'; registered: .*'clustered', 'em'"
    ):
        model_kind("nope")
    assert "em2" not in model_kinds()


def _grouped(n=40):
    g = torch.Generator().manual_seed(1)
    x = torch.rand(n, 3, generator=g, dtype=torch.float64)
    y = torch.where(x[:, :1] > 0.5, 1.0, -1.0) + 0.3 * x[:, 1:2]
    return x, y.to(torch.float64)


def test_building_from_settings_matches_direct_construction():
    x, y = _grouped()
    groups = {"a": slice(0, 1), "b": slice(1, 3)}
    gp = GPOptions(max_iter=20, lengthscale_prior=0.5, noise_floor="auto")
    settings = ModelSettings(n_experts=2, groups=groups, gate=("a",), experts=("b",), seed=3, gp=gp)
    built = model_kind("em").fit_new(x, y, settings, fit={"max_iter": 2, "n_restarts": 1})
    direct = MixtureOfGPExperts(2, groups=groups, gate_features=["a"], expert_features=["b"], gp=gp)
    fit_em(direct, x, y, seed=3, max_iter=2, n_restarts=1)
    assert built.config() == direct.config() and built.gp is gp  # the settings, whole
    assert torch.equal(built.predict(x).mean, direct.predict(x).mean)
    # without GP settings, the kind's default: the mixture's own
    assert model_kind("em").build(n_experts=2).gp is MIXTURE_GP
    # the options whole (as a study's config holds them) fit the same model; the seed is
    # the settings'
    whole = model_kind("em").fit_new(x, y, settings, fit=EMOptions(max_iter=2, n_restarts=1))
    assert torch.equal(whole.predict(x).mean, direct.predict(x).mean)
    with pytest.raises(
        InputError, match=r"fit holds SVIOptions, but model kind 'em' takes EMOptions"
    ):
        model_kind("em").fit_new(x, y, settings, fit=SVIOptions())
    with pytest.raises(InputError, match=r"model kind 'clustered' takes no options"):
        model_kind("clustered").fit_new(x, y, n_experts=2, fit=EMOptions())
    with pytest.raises(InputError, match="fit must be a kind's fitting options"):
        ModelSettings(2, fit=[("max_iter", 2)])

    clustered = model_kind("clustered").build(n_experts=2, seed=4, gp=gp)
    assert clustered.config() == ClusteredGPModel(2, seed=4, gp=gp).config() and clustered.gp is gp
    assert model_kind("clustered").build(n_experts=2).gp == GPOptions()
    with pytest.raises(InputError, match="gate"):
        model_kind("clustered").build(n_experts=2, gate=("a",))
    with pytest.raises(InputError, match="cannot be built"):
        model_kind("transition").build()
    with pytest.raises(InputError, match="length-scale prior"):
        model_kind("svi").build(gp=GPOptions(lengthscale_prior=True))
    with pytest.raises(InputError, match=r"gp must be GPOptions"):
        ModelSettings(2, gp={"max_iter": 5})  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="lengthscale_prior"):
        ModelSettings(2, lengthscale_prior=True)  # type: ignore[call-arg]
    with pytest.raises(InputError, match="n_experts"):
        ModelSettings(n_experts=0)
    with pytest.raises(InputError, match="gate"):
        ModelSettings(gate="a")  # type: ignore[arg-type]


def test_generic_fit_dispatches_on_the_model(tmp_path):
    x, y = _grouped()
    history = fit(MixtureOfGPExperts(1), x, y, EMOptions(max_iter=1), n_restarts=1)
    assert history.n_iter >= 1
    with pytest.raises(InputError, match="takes no fitting options"):
        fit(ClusteredGPModel(2), x, y, seed=1)
    with pytest.raises(InputError, match="not a registered kind"):
        fit(object(), x, y)
    assert models.fit is fit
