"""Typed, validated options of the model fits: EM, SVI and the exact and sparse GP experts.

Every fitting keyword of `fit_em` / `fit_em_path` (`EMOptions`), of `fit_svi` (`SVIOptions`),
of a `GPExpert` (`GPOptions`) and of a `SparseGPExpert` (`SparseGPOptions`) is a field here,
with the same name and default. The options are frozen dataclasses that validate and
normalise their fields on construction, so a value that reaches a fit has been checked
exactly once, and a configuration can hold them under the names the fits use. Each fit
takes ``options=`` and keyword overrides of single fields (`resolve_options`), e.g.
``fit_em(model, X, Y, EMOptions(max_iter=20), seed=3)``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import torch
from torch import Tensor

from probaff._checks import check_count, check_finite, check_positive, default_or_instance
from probaff.errors import InputError
from probaff.models.initialization import check_initialization

__all__ = [
    "AUTO_NOISE_FLOOR",
    "DEFAULT_N_INDUCING",
    "MIXTURE_GP",
    "NOISE_BOUNDS",
    "OUTPUTSCALE_BOUNDS",
    "EMOptions",
    "GPOptions",
    "SVIOptions",
    "SparseGPOptions",
    "check_hyper_rows",
    "check_lengthscale_prior",
    "refuse_flat_gp_keywords",
    "resolve_options",
]

OUTPUTSCALE_BOUNDS = (1e-4, 1e4)
"""Open interval of a GP's signal variance, in standardised output units."""

DEFAULT_N_INDUCING = 128
"""Inducing points per output when `n_inducing` is None (capped by the training rows).

Measured on `probaff.models.synthetic.regime_features` (D = 101, E = 6, M = 3): with one
M-step on the true regimes, 256 points give a held-out NLPD 0.03 nats per output better than
128 at N = 2,000 and 10,000, for 2.5 to 4 times the CPU time. The default EM fit of
N = 10,000 rows (one thread, loaded machine) took 163 CPU-s with 128 points and
`hyper_rows` = 2,048 (held-out NLPD -4.706 summed over the outputs, RMSE 0.453), and 716
CPU-s with 256 points and `hyper_rows` = 4,096 (NLPD -4.966, RMSE 0.453): 0.04 nats per
output for 4.4 times the time, which would put the fit past five minutes."""

NOISE_BOUNDS = (1e-6, 1e2)
"""Open interval of a GP's observation-noise variance, in standardised output units."""

AUTO_NOISE_FLOOR = 0.01
"""The noise floor of ``GPOptions(noise_floor="auto")``, as a fraction of each output's
standard deviation over the training targets."""

OptionsT = TypeVar("OptionsT")


def resolve_options(
    options_type: type[OptionsT], options: OptionsT | None, overrides: Mapping[str, Any]
) -> OptionsT:
    """`options` (or the defaults) with the given fields replaced, validated again.

    Args:
        options_type: The options dataclass, e.g. `EMOptions`.
        options: Base options; None for ``options_type()``.
        overrides: Field name -> value; every entry replaces the base value (None included,
            where None is a valid value of the field).

    Returns:
        Validated options of `options_type`.

    Raises:
        InputError: If `options` is of another type, an override names no field, or a value
            is out of range.
    """
    what = f"a {options_type.__name__}"
    base = default_or_instance("options", options, options_type, options_type, what)
    names = {f.name for f in dataclasses.fields(options_type)}  # type: ignore[arg-type]
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise InputError(
            f"unknown fitting option(s) {unknown}; {options_type.__name__} has {sorted(names)}."
        )
    return dataclasses.replace(base, **overrides) if overrides else base  # type: ignore[type-var]


def _set(options: Any, name: str, value: Any) -> None:
    object.__setattr__(options, name, value)


def _check_bool(name: str, value: Any) -> bool:
    """`value` as a bool; True, False, 1, 0 and numpy booleans are accepted."""
    try:
        ok = not isinstance(value, (str, bytes)) and bool(value in (0, 1))
    except (TypeError, ValueError, RuntimeError):
        ok = False
    if not ok:
        raise InputError(f"{name} must be True or False, got {value!r}.")
    return bool(value)


def check_lengthscale_prior(value: Any) -> bool | float:
    """`lengthscale_prior` as False (off), True (on, at the default width) or a width.

    Args:
        value: False, True (the prior at `probaff.models.experts.kernels.LENGTHSCALE_PRIOR_SCALE`)
            or the prior's width, the standard deviation of the log length scales (a finite
            number > 0). The integers 0 and 1 are False and True.

    Returns:
        A builtin bool, or the width as a float.

    Raises:
        InputError: Naming `lengthscale_prior`, for anything else.
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)) and value in (0, 1):
        return bool(value)  # 0 and 1 as switches (1 is also the default width)
    width = None
    if isinstance(value, (int, float, np.integer, np.floating)):
        width = float(value)
    if width is None or not math.isfinite(width) or width <= 0.0:
        raise InputError(
            "lengthscale_prior must be True, False or the prior's width (the standard "
            f"deviation of the log length scales, a finite number > 0), got {value!r}."
        )
    return width


def _check_init(init: Any, *, extra: tuple[type, ...] = ()) -> None:
    """A named initialisation, or responsibilities `(N, M)` (checked against the data later)."""
    if isinstance(init, str):
        check_initialization(init)
    elif not isinstance(init, (Tensor, *extra)):
        raise InputError(
            f"init must be an initialisation name or responsibilities (N, M), got "
            f"{type(init).__name__}."
        )


@dataclass(frozen=True)
class EMOptions:
    """Settings of an EM fit of a `MixtureOfGPExperts` (`fit_em`, `fit_em_path`).

    Attributes:
        init: ``"auto"``, ``"effects"``, ``"joint"``, ``"grow"``, or responsibilities
            `(N, M)` that start one run (see `fit_em`).
        n_restarts: Starts tried for each `M` (the grown one counts).
        screen_iter: Iterations every start runs before only the best `n_finish` are run
            to convergence (the "small EM" strategy of Biernacki et al., 2003); None runs
            every start to convergence.
        n_finish: Screened starts run to convergence, the best by their screened objective
            first; the best of them is kept. The first gets `split_merge` rounds, the
            others one. A grown start is warm and can lead the screening although a cold
            start would end higher; finishing two catches that, for about a third more
            time.
        split_merge: Rounds of split-and-merge moves tried after convergence (0: none).
            On the small data sets of ``benchmarks/mixture_cost.py`` they cost 28-42 % of
            a fit without moving the mean held-out NLPD, but they rescue unlucky starts: on
            `probaff.models.synthetic.softmax_regimes` (M = 3, data seeds 0-4) they turned
            a miss of 1.4 nats per held-out point (N = 400, seed 0) and one of 0.12
            (N = 200, seed 0) into the fit the other seeds find, for 20-75 % more CPU time.
        max_iter: Maximum number of EM iterations of a run.
        tol: Convergence tolerance on the objective per sample, >= 0.
        n_init: Restarts of each initial Gaussian mixture: the first seeded by k-means,
            the others by rows drawn from the data; the most likely is kept. k-means alone
            split RAND HIE's visits (spikes at 0 and 1 visit beside a long tail) down the
            middle at every seed; with 20 restarts the spike was found at each of seeds
            0-4 on three splits (`benchmarks/mixture_starts.py`).
        seed: Seed of the initialisations (an integer >= 0); the rest of EM is
            deterministic.
        prune_below: Responsibilities below this are 0 in the experts' M-step, >= 0 (and
            below ``1 / n_experts``, checked by the fit).
        min_size: Minimum summed responsibility of an expert before it is repaired, >= 0.
        gp_max_iter: L-BFGS iterations of the first M-step of a cold start; None for the
            model's ``gp.max_iter`` (its experts' `GPOptions`).
        warm_max_iter: L-BFGS iterations of later M-steps (and of every M-step of a grown
            start), warm-started from the previous hyperparameters.
        anneal: Temper the E-step (deterministic annealing).
        anneal_start: First inverse temperature of the annealing, in (0, 1].
        anneal_iter: Iterations over which the inverse temperature rises to 1.
        search_rows: With more training rows than this, `fit_em` searches for the fit (the
            path over `M`, the screened starts, split-and-merge) on a seeded random subset
            of this many rows, then refines the kept fit on every row by up to `max_iter`
            EM iterations from its responsibilities there (coarse to fine). None searches
            on every row. `fit_em_path` always uses every row.
        search_restarts: Starts tried by the coarse search on the `search_rows` subset
            (`n_restarts` on smaller data). The subset search costs the same at every
            `N`, so it affords more starts: on statsmodels' RAND HIE visits (a target with
            spikes at 0 and 1 visit), one seeded 1,000-row subset in four missed the
            second spike with 3 starts (held-out NLPD 0.02 against -0.49); with 6 none
            of them did.

    Raises:
        InputError: On construction, naming the first field out of range.
    """

    init: str | Tensor = "auto"
    n_restarts: int = 3
    screen_iter: int | None = 2
    n_finish: int = 1
    split_merge: int = 2
    max_iter: int = 10
    tol: float = 1e-3
    n_init: int = 20
    seed: int = 0
    prune_below: float = 1e-4
    min_size: float = 3.0
    gp_max_iter: int | None = None
    warm_max_iter: int = 8
    anneal: bool = False
    anneal_start: float = 0.1
    anneal_iter: int = 4
    search_rows: int | None = 1000
    search_restarts: int = 6

    def __post_init__(self) -> None:
        """Validate every field and store counts and numbers as builtin types."""
        _check_init(self.init)
        for name in (
            "n_restarts",
            "search_restarts",
            "n_finish",
            "max_iter",
            "n_init",
            "warm_max_iter",
        ):
            _set(self, name, check_count(name, getattr(self, name)))
        _set(self, "split_merge", check_count("split_merge", self.split_merge, minimum=0))
        _set(self, "seed", check_count("seed", self.seed, minimum=0))
        for name in ("screen_iter", "gp_max_iter", "search_rows"):
            value = getattr(self, name)
            _set(self, name, None if value is None else check_count(name, value))
        for name in ("tol", "prune_below", "min_size"):
            check_positive(name, getattr(self, name), allow_zero=True)
            _set(self, name, float(getattr(self, name)))
        _set(self, "anneal", _check_bool("anneal", self.anneal))
        check_positive("anneal_start", self.anneal_start)
        if not self.anneal_start <= 1.0:
            raise InputError(f"anneal_start must be in (0, 1], got {self.anneal_start!r}.")
        _set(self, "anneal_start", float(self.anneal_start))
        _set(self, "anneal_iter", check_count("anneal_iter", self.anneal_iter))


@dataclass(frozen=True)
class SVIOptions:
    """Settings of an SVI fit of a `VariationalMixtureOfGPExperts` (`fit_svi`).

    Attributes:
        n_steps: SVI steps.
        batch_size: Minibatch size (capped at `N` by the fit).
        lr: Adam step size, > 0.
        n_init: Restarts of the initial Gaussian mixture (as `EMOptions.n_init`).
        seed: Seed of the initialisation and the minibatches (an integer >= 0).
        init: ``"auto"``, ``"grow"``, ``"effects"``, ``"joint"``, a fitted
            `MixtureOfGPExperts`, or responsibilities `(N, M)` (see `fit_svi`).
        init_rows: Rows of the exact EM fit behind ``"grow"`` and ``"auto"`` (a seeded
            random subset when `N` is larger). At `N` = 1,000 on
            `probaff.models.synthetic.regime_features` a start from 400 rows left VI's RMSE
            10.5 % above EM's, a start from every row 1.4 % below it.
        natural_step: Natural-gradient step of every q(u) per minibatch, in (0, 1] (a
            full-batch step takes 1, the exact update).
        gate_lr_scale: Adam step of the gate, relative to `lr`, when an exact mixture gave
            it (0 keeps it; without such a start the gate takes `lr`).
        hyper_lr_scale: Adam step of the kernels, means, noise and inducing inputs,
            relative to `lr`, when an exact mixture gave them (0 keeps them).

    Raises:
        InputError: On construction, naming the first field out of range.
    """

    n_steps: int = 1500
    batch_size: int = 64
    lr: float = 0.02
    n_init: int = 20
    seed: int = 0
    init: Any = "auto"
    init_rows: int = 2000
    natural_step: float = 0.1
    gate_lr_scale: float = 0.0
    hyper_lr_scale: float = 0.0

    def __post_init__(self) -> None:
        """Validate every field and store counts and numbers as builtin types."""
        for name in ("n_steps", "batch_size", "n_init", "init_rows"):
            _set(self, name, check_count(name, getattr(self, name)))
        check_positive("lr", self.lr)
        _set(self, "lr", float(self.lr))
        check_positive("natural_step", self.natural_step)
        if float(self.natural_step) > 1.0:
            raise InputError(f"natural_step must lie in (0, 1], got {self.natural_step!r}.")
        _set(self, "natural_step", float(self.natural_step))
        for name in ("gate_lr_scale", "hyper_lr_scale"):
            check_positive(name, getattr(self, name), allow_zero=True)
            _set(self, name, float(getattr(self, name)))
        _set(self, "seed", check_count("seed", self.seed, minimum=0))
        _check_init(self.init, extra=(torch.nn.Module,))


def _check_inside(name: str, value: Any, bounds: tuple[float, float]) -> float:
    """`value` as a float, or `InputError` unless it is finite and strictly inside `bounds`."""
    check_positive(name, value)
    v = float(value)
    if not bounds[0] < v < bounds[1]:
        raise InputError(
            f"{name} must lie strictly between {bounds[0]:g} and {bounds[1]:g} "
            f"(standardised units), got {value!r}."
        )
    return v


def _check_noise_floor(noise_floor: Any) -> float | tuple[float, ...] | str | None:
    """None, ``"auto"``, or finite non-negative standard deviation(s): a float or a tuple."""
    if noise_floor is None or (isinstance(noise_floor, str) and noise_floor == "auto"):
        return noise_floor
    try:
        floor = torch.as_tensor(noise_floor, dtype=torch.float64)
    except (TypeError, ValueError, RuntimeError):
        floor = None
    if floor is None or isinstance(noise_floor, str):
        raise InputError(
            f"noise_floor must be 'auto', None or non-negative standard deviations, got "
            f"{noise_floor!r}."
        )
    check_finite("noise_floor", floor)
    if bool((floor < 0).any()):
        raise InputError(
            f"noise_floor must be one non-negative standard deviation or one per output, got "
            f"{noise_floor!r}."
        )
    if floor.dim() == 0:
        return float(floor)
    return tuple(float(v) for v in floor.flatten())


@dataclass(frozen=True)
class GPOptions:
    """Settings of an exact `GPExpert` and its fit (and of the experts of a mixture).

    The defaults are a single `GPExpert`'s. A `MixtureOfGPExperts` takes its experts' settings
    as one `GPOptions` too; its default is `MIXTURE_GP`
    (``GPOptions(lengthscale_prior=True, noise_floor="auto")``).

    Attributes:
        max_iter: L-BFGS iterations per call to `GPExpert.fit`.
        lengthscale_prior: Put the dimension-scaled log-normal prior on the length scales:
            False, True (at `probaff.models.experts.kernels.LENGTHSCALE_PRIOR_SCALE`) or its width
            (the standard deviation of the log length scales).
        noise_floor: Smallest observation-noise standard deviation, in output units: None
            (no floor), one value, one value per output `(E,)` (stored as a tuple), or
            ``"auto"``: `AUTO_NOISE_FLOOR` (1 %) of each output's standard deviation over
            the training targets. A `GPExpert` resolves ``"auto"`` from the targets of each
            `fit` or `condition` (every row given, whatever its weight); a
            `MixtureOfGPExperts` resolves it once from its whole training set and gives its
            experts the numbers.
        outputscale: Initial signal variance, inside `OUTPUTSCALE_BOUNDS`.
        noise: Initial observation-noise variance, inside `NOISE_BOUNDS`.

    Raises:
        InputError: On construction, naming the first field out of range.
    """

    max_iter: int = 50
    lengthscale_prior: bool | float = False
    noise_floor: float | Sequence[float] | str | None = None
    outputscale: float = 1.0
    noise: float = 0.1

    def __post_init__(self) -> None:
        """Validate every field and store it as builtin types."""
        _set(self, "max_iter", check_count("max_iter", self.max_iter))
        _set(self, "lengthscale_prior", check_lengthscale_prior(self.lengthscale_prior))
        _set(self, "noise_floor", _check_noise_floor(self.noise_floor))
        outputscale = _check_inside("outputscale", self.outputscale, OUTPUTSCALE_BOUNDS)
        _set(self, "outputscale", outputscale)
        _set(self, "noise", _check_inside("noise", self.noise, NOISE_BOUNDS))


MIXTURE_GP = GPOptions(lengthscale_prior=True, noise_floor="auto")
"""The experts' settings of a `MixtureOfGPExperts` given no ``gp``.

50 L-BFGS iterations per expert fit, the dimension-scaled log-normal length-scale prior at its
default width, a noise floor of 1 % of each effect's standard deviation over the mixture's
training set (``"auto"``, resolved once per fit from the whole training set, not from each
expert's weighted share), and `GPOptions`' initial signal and noise variances. They differ
from a single `GPExpert`'s defaults (`GPOptions()`: no prior, no floor): without the prior, a
mixture of 3 experts on 250 rows of 101 features predicted held-out rows with NLPD 4.7
against 1.3 with it (`probaff.models.synthetic.regime_features`)."""


def refuse_flat_gp_keywords(what: str, given: Iterable[str], flat: Mapping[str, str]) -> None:
    """Refuse the old flat GP keywords among `given`, naming the ``gp=GPOptions(...)`` to use.

    Args:
        what: The start of the message, e.g. ``"MixtureOfGPExperts takes its experts'
            settings"``.
        given: The keyword names a constructor was called with.
        flat: Old keyword -> its field of `GPOptions`
            (`probaff.models.mixture.model.FLAT_GP_KEYWORDS`, or the transition models'
            `probaff.models.transitions.transition_base.TRANSITION_FLAT_GP_KEYWORDS`).

    Raises:
        InputError: If `given` holds any of `flat`'s keywords.
    """
    old = sorted(set(given) & set(flat))
    if old:
        fields = ", ".join(f"{flat[k]}=..." for k in old)
        raise InputError(
            f"{what} as one GPOptions: use gp=GPOptions({fields}) instead of {', '.join(old)}."
        )


def check_hyper_rows(hyper_rows: Any, n_inducing: int | None) -> int | None:
    """`hyper_rows` as an `int` (or None), or `InputError` naming it when it is too small.

    A sparse expert chooses its `m` inducing inputs among the `hyper_rows` rows it fits its
    hyperparameters on, so fewer rows than inducing points would silently cut `m` to
    `hyper_rows` and fit the hyperparameters of a GP on a handful of rows (with
    ``hyper_rows=1``, one row: an EM objective of -845 where every row gives 33.7). The floor
    is therefore the inducing points asked for: `n_inducing`, or `DEFAULT_N_INDUCING` when it
    is None. Training sets smaller than `hyper_rows` are unaffected (every row is used).

    Args:
        hyper_rows: Rows the hyperparameters are chosen on, or None for every row.
        n_inducing: Inducing points per output, or None for `DEFAULT_N_INDUCING`.

    Returns:
        `hyper_rows` as a builtin `int`, or None.
    """
    if hyper_rows is None:
        return None
    rows = check_count("hyper_rows", hyper_rows)
    floor = DEFAULT_N_INDUCING if n_inducing is None else int(n_inducing)
    if rows < floor:
        which = f"n_inducing={n_inducing}" if n_inducing is not None else "the default n_inducing"
        raise InputError(
            f"hyper_rows={hyper_rows!r} is below the {floor} inducing points ({which}) that are "
            f"chosen among those rows; give hyper_rows >= {floor} (2048 by default), or None "
            "to fit on every row."
        )
    return rows


@dataclass(frozen=True)
class SparseGPOptions(GPOptions):
    """Settings of an inducing-point `SparseGPExpert` and its fit.

    The fields of `GPOptions` (`max_iter`, `lengthscale_prior`, `noise_floor`, `outputscale`,
    `noise`) mean the same here; three are added.

    Attributes:
        n_inducing: Inducing points `m` per output; None for 128. At most the number of
            samples with non-zero weight are used (`MixtureOfGPExperts` refuses a value
            above its `N` training rows).
        learn_inducing: Optimise the inducing inputs with the hyperparameters (each fit
            still starts them from the greedy selection on the expert's weighted samples);
            False keeps the selection fixed, which is faster.
        hyper_rows: Rows the hyperparameters and the inducing inputs are chosen on: an
            expert holding more samples of non-zero weight maximises the bound of a uniform
            random subset of this many of them (with their weights; the same subset for the
            same data), then conditions on all of them. This is Chalupka, Williams & Murray's
            (2013) "subset of data for the hyperparameters, all data for the predictions",
            which makes a fit's cost :math:`O(N m^2)` with a constant independent of `N`.
            None optimises on every sample. At least `n_inducing` (`DEFAULT_N_INDUCING`
            when None): the inducing inputs are chosen among these rows
            (`check_hyper_rows`).

    Raises:
        InputError: On construction, naming the first field out of range.
    """

    n_inducing: int | None = None
    learn_inducing: bool = False
    hyper_rows: int | None = 2048

    def __post_init__(self) -> None:
        """Validate every field and store it as builtin types."""
        super().__post_init__()
        for name in ("n_inducing", "hyper_rows"):
            if getattr(self, name) is not None:
                _set(self, name, check_count(name, getattr(self, name)))
        check_hyper_rows(self.hyper_rows, self.n_inducing)
        _set(self, "learn_inducing", _check_bool("learn_inducing", self.learn_inducing))
