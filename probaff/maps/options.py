"""Typed, validated options of affordance-map inference: the BP solver and the MRF parameters.

Every default of the maps is written here, once: the belief-propagation solver settings
(`BPOptions`) and the MRF's couplings with the planner's reward weight (`MRFParams`). Both are
frozen dataclasses that validate and normalise their fields on construction, so a value that
reaches a solver has been checked exactly once.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import torch

from probaff._checks import check_count, default_or_instance
from probaff.errors import InputError

__all__ = [
    "DEFAULT_ALPHA",
    "DEFAULT_COUPLING",
    "DEFAULT_DAMPING",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_TOL",
    "MAX_COUPLING",
    "THESIS_SYMMETRY_COUPLING",
    "BPOptions",
    "MRFParams",
    "check_alpha",
    "check_coupling",
    "resolve_bp_options",
]

DEFAULT_DAMPING = 0.3
"""Weight of the previous message in each BP update."""

DEFAULT_TOL = 1e-6
"""Stop BP when no message (half log-ratio) changes by this much or more."""

DEFAULT_MAX_ITERATIONS = 200
"""Iteration budget of one BP call."""

DEFAULT_COUPLING = 0.4
"""Default Ising strength ``J`` between equal directions of neighbouring boxes."""

DEFAULT_ALPHA = 0.8
"""Weight ``alpha`` of the reward against the travel cost in ``G = alpha R - (1 - alpha) C``."""

THESIS_SYMMETRY_COUPLING = DEFAULT_COUPLING
"""``J_sym`` of the thesis's symmetry pairs (chapter 3, §3.3.4 and §3.4).

§3.3.4 introduces the symmetry pairs ("if a cell is not pushable upward, the cell above should
be not pushable down") as part of the one pairwise factor ``ψ_ij = exp(J x_i x_j)``, and §3.4
builds every pairwise potential "using the Ising model with J = 0.4". The thesis gives no
separate number for the pairs, so they take that same ``J``. `MRFParams` leaves them out by
default; the affordance-map study turns them on at this value."""

MAX_COUPLING = 5.0
"""Largest accepted ``|J|`` (and ``|J_sym|``): ``exp(2 * 5) ≈ 2.2e4`` already makes
neighbours almost deterministic, and larger values only cost numerical precision."""


def check_coupling(name: str, value: float) -> float:
    """Return `value` as a float, or raise `InputError` unless it is finite with ``|J| <= 5``.

    Args:
        name: What the value is, as the user knows it (e.g. ``"coupling"``).
        value: The coupling strength.

    Returns:
        The coupling as a Python float.

    Raises:
        InputError: Naming `name` and the accepted range, for a value that is not a number
            (a bool included), not finite (NaN, inf) or stronger than `MAX_COUPLING`.
    """
    if isinstance(value, bool):
        raise InputError(f"{name} must be a number, got {value!r}; pass e.g. {DEFAULT_COUPLING}.")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}.") from None
    if not math.isfinite(v):
        raise InputError(
            f"{name} must be a finite number, got {value!r}; pass a coupling with "
            f"|{name}| <= {MAX_COUPLING} (the thesis's J is {DEFAULT_COUPLING})."
        )
    if abs(v) > MAX_COUPLING:
        raise InputError(
            f"{name} must be finite with |{name}| <= {MAX_COUPLING}, got {value!r}; stronger "
            "couplings make neighbouring boxes deterministic copies of each other."
        )
    return v


def check_alpha(alpha: float) -> float:
    """Return `alpha` as a float, or raise `InputError` unless it is a number in [0, 1].

    Args:
        alpha: Weight of the reward in the information gain.

    Returns:
        `alpha` as a Python float.
    """
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise InputError(f"alpha must be a number in [0, 1], got {alpha!r}.") from None
    if not (math.isfinite(a) and 0.0 <= a <= 1.0):
        raise InputError(
            f"alpha must lie in [0, 1] (1 weighs only the entropy reduction, 0 only the travel "
            f"cost), got {alpha!r}."
        )
    return a


@dataclass(frozen=True)
class BPOptions:
    """Settings of a loopy belief propagation run (generic, grid or inside inference).

    Attributes:
        damping: Weight of the previous message in each update, in ``[0, 1)``.
        tol: Converged once every message changes by less than this (half log-ratio), a
            finite number >= 0.
        max_iterations: Maximum number of parallel updates (a positive integer).
        dtype: torch.float32 or torch.float64, the floating dtype of messages and marginals.

    Raises:
        InputError: On construction, for any field out of range.
    """

    damping: float = DEFAULT_DAMPING
    tol: float = DEFAULT_TOL
    max_iterations: int = DEFAULT_MAX_ITERATIONS
    dtype: torch.dtype = torch.float32

    def __post_init__(self) -> None:
        """Validate every field and store counts and numbers as builtin types."""
        damping, tol = self.damping, self.tol
        if isinstance(damping, bool) or not (
            isinstance(damping, (int, float)) and 0.0 <= float(damping) < 1.0
        ):
            raise InputError(
                f"damping must be a number in [0, 1) (the weight of the previous message), "
                f"got {damping!r}."
            )
        if isinstance(tol, bool) or not (
            isinstance(tol, (int, float)) and math.isfinite(tol) and tol >= 0
        ):
            raise InputError(f"tol must be a finite number >= 0, got {tol!r}.")
        if self.dtype not in (torch.float32, torch.float64):
            raise InputError(f"dtype must be torch.float32 or torch.float64, got {self.dtype}.")
        object.__setattr__(self, "damping", float(damping))
        object.__setattr__(self, "tol", float(tol))
        object.__setattr__(
            self, "max_iterations", check_count("max_iterations", self.max_iterations)
        )


def resolve_bp_options(options: BPOptions | None = None, **overrides: Any) -> BPOptions:
    """`options` (or the defaults) with every override that is not None applied.

    Args:
        options: Base options; None for `BPOptions()`.
        **overrides: ``damping``, ``tol``, ``max_iterations`` or ``dtype``; None entries
            keep the base value.

    Returns:
        Validated options.

    Raises:
        InputError: For an unknown override or a value out of range.
    """
    base = default_or_instance("options", options, BPOptions, BPOptions, "a BPOptions")
    names = {f.name for f in dataclasses.fields(BPOptions)}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise InputError(f"unknown BP option(s) {unknown}; BPOptions has {sorted(names)}.")
    given = {k: v for k, v in overrides.items() if v is not None}
    return dataclasses.replace(base, **given) if given else base


@dataclass(frozen=True)
class MRFParams:
    """Parameters of the affordance MRF and of the information-gain score built on it.

    Attributes:
        coupling: Ising strength ``J`` between equal directions of 4-neighbouring boxes,
            ``|J| <= MAX_COUPLING``.
        alpha: Weight of the reward in ``G = alpha R - (1 - alpha) C``, in [0, 1].
        symmetry_coupling: ``J_sym`` of the up/down and left/right symmetry factors (same
            range), or None to leave them out.
        along_coupling: Ising strength between neighbours that lie along the direction
            itself, or None to use `coupling` (see `AffordanceGraph`).

    Raises:
        InputError: On construction, for a coupling or alpha out of range.
    """

    coupling: float = DEFAULT_COUPLING
    alpha: float = DEFAULT_ALPHA
    symmetry_coupling: float | None = None
    along_coupling: float | None = None

    def __post_init__(self) -> None:
        """Validate every field once and store it as a builtin float (or None)."""
        object.__setattr__(self, "coupling", check_coupling("coupling", self.coupling))
        object.__setattr__(self, "alpha", check_alpha(self.alpha))
        for name in ("symmetry_coupling", "along_coupling"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, check_coupling(name, value))
