"""Settings of the affordance-map study: its config, the world it runs in and smoke sizes."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import InitVar, dataclass
from types import MappingProxyType
from typing import Any, ClassVar

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.experiments.base import StudyConfig
from probaff.maps.options import THESIS_SYMMETRY_COUPLING, MRFParams
from probaff.sim.warehouse_config import SENSOR_KINDS, WarehouseSpec, load_warehouse

__all__ = ["NOISY_SENSOR", "SMOKE", "STUDY_MRF", "AffordanceMapConfig", "world"]

NOISY_SENSOR = 0.2
"""Range noise (m) of the degraded idealised scanner (``sensor="scanner"``): the world file's
0.01 m makes the classifier almost certain; 0.2 m leaves it unsure of a few boxes per map."""

STUDY_MRF = MRFParams(symmetry_coupling=THESIS_SYMMETRY_COUPLING)
"""The study's MRF: the thesis's chapter 3 MRF (§3.3.4, §3.4), Ising ``J = 0.4`` between the
same direction of neighbouring boxes plus the up/down and left/right symmetry pairs at the
same ``J`` (`probaff.maps.options.THESIS_SYMMETRY_COUPLING`), and ``alpha = 0.8``.
``--symmetry-coupling none`` leaves the symmetry pairs out."""

SMOKE: Mapping[str, Any] = MappingProxyType(
    {"n_maps": 2, "train_maps": 2, "max_steps": 3, "progress": False}
)
"""Sizes of a tiny run that checks the whole pipeline."""


@dataclass(frozen=True, kw_only=True)
class AffordanceMapConfig(StudyConfig):
    """Settings of the affordance-map study.

    Attributes:
        out: Output folder.
        seed: Seed of the training maps, the test maps, the starts and all sensor noise.
        n_maps: Test maps.
        train_maps: Maps the classifier is trained on.
        mrf: The MRF's couplings ``J``, ``J_sym``, ``J_along`` and the reward weight
            ``alpha`` of ``G = alpha R - (1 - alpha) C`` (validated by `MRFParams`); the
            default is `STUDY_MRF`, the thesis's MRF with its symmetry pairs. The
            keywords ``alpha``, ``coupling``, ``symmetry_coupling`` and ``along_coupling``
            are accepted by the constructor as shorthands that replace those fields of
            `mrf`, and are readable as properties.
        max_steps: Most pushes per map and policy.
        sensor_noise: Range noise (m) of the idealised scanner; None keeps the world file's
            value. Only with ``sensor="scanner"``.
        sensor: The robot's sensor, one of `SENSOR_KINDS`: ``"camera"`` (the head's depth
            camera of chapter 2) or ``"scanner"`` (the idealised range scanner); None keeps
            the world file's (the camera).
        entropy_target: The map entropy to reach, as a share of the map's initial one (both
            under the MRF): the summary counts each policy's steps until its map gets there.
        stop_at_no_gain: Stop the information-gain loop when every ``G < 0`` (the thesis's
            rule); False keeps it pushing to `max_steps`, for a step-by-step comparison.
    """

    out: str = "results/affordance_map"
    n_maps: int = 20
    train_maps: int = 20
    mrf: MRFParams = STUDY_MRF
    max_steps: int = 20
    sensor_noise: float | None = None
    sensor: str | None = None
    entropy_target: float = 0.5
    stop_at_no_gain: bool = True
    alpha: InitVar[float | None] = None
    coupling: InitVar[float | None] = None
    symmetry_coupling: InitVar[float | None] = None
    along_coupling: InitVar[float | None] = None

    RUN_ONLY: ClassVar[frozenset[str]] = frozenset(
        {"n_maps", "out", "workers", "scheduler", "progress", "entropy_target"}
    )
    """Fields that do not change any map's result (each map's result is keyed by its
    index, so more maps only add results)."""

    SMOKE: ClassVar[Mapping[str, Any]] = SMOKE
    SHORTHANDS: ClassVar[Mapping[str, tuple[str, Any, str]]] = MappingProxyType(
        {
            "--no-stop": (
                "stop_at_no_gain",
                False,
                "keep the information-gain loop pushing when every gain is negative "
                "(the same as --no-stop-at-no-gain)",
            )
        }
    )

    def __post_init__(
        self,
        alpha: float | None,
        coupling: float | None,
        symmetry_coupling: float | None,
        along_coupling: float | None,
    ) -> None:
        """Fold the shorthand MRF keywords into `mrf` (validated there, once)."""
        given = {
            k: v
            for k, v in (
                ("alpha", alpha),
                ("coupling", coupling),
                ("symmetry_coupling", symmetry_coupling),
                ("along_coupling", along_coupling),
            )
            if v is not None
        }
        if not isinstance(self.mrf, MRFParams):
            raise InputError(f"mrf must be an MRFParams, got {type(self.mrf).__name__}.")
        if given:
            object.__setattr__(self, "mrf", dataclasses.replace(self.mrf, **given))

    def check(self) -> dict[str, Any]:
        """Check the study's settings; return its counts as builtin ints.

        Raises:
            InputError: For a setting out of range.
        """
        n_maps = check_count("n_maps", self.n_maps)
        train_maps = check_count("train_maps", self.train_maps)
        max_steps = check_count("max_steps", self.max_steps, minimum=0)
        if self.sensor_noise is not None and not (
            math.isfinite(self.sensor_noise) and self.sensor_noise >= 0
        ):
            raise InputError(f"sensor_noise must be a number >= 0, got {self.sensor_noise!r}.")
        world(self.sensor_noise, self.sensor)  # the sensor's name and noise, checked
        if not (isinstance(self.entropy_target, (int, float)) and 0 < self.entropy_target < 1):
            raise InputError(
                f"entropy_target must be a share in (0, 1) of the initial map entropy, got "
                f"{self.entropy_target!r}."
            )
        return {"n_maps": n_maps, "train_maps": train_maps, "max_steps": max_steps}

    def fingerprint(self) -> str:
        """Short hash of every setting that changes a map's result (see `RUN_ONLY`)."""
        # 4: interior wall blocks; the world files count too, so an edited world never reuses
        # a stored map.
        return self.tag(version=4, world=("warehouse.yaml", "camera.yaml"))


def _mrf_property(name: str) -> property:
    """A read-only view of ``config.mrf.<name>`` under the old flat field name."""
    return property(
        lambda self: getattr(self.mrf, name), doc=f"Shorthand for ``mrf.{name}`` (see `MRFParams`)."
    )


# The InitVar defaults are class attributes; replace them by views of `mrf` once the
# dataclass machinery has built __init__ (which keeps None as the keywords' default).
for _name in ("alpha", "coupling", "symmetry_coupling", "along_coupling"):
    setattr(AffordanceMapConfig, _name, _mrf_property(_name))
del _name


def world(sensor_noise: float | None = None, sensor: str | None = None) -> WarehouseSpec:
    """The warehouse world, with its sensor and the scanner's range noise replaced if given.

    Args:
        sensor_noise: Range noise (m) of the idealised scanner; None keeps the world file's.
        sensor: One of `SENSOR_KINDS`; None keeps the world file's.

    Raises:
        InputError: For an unknown sensor, or a range noise given for the camera (whose noise
            model lives in ``worlds/camera.yaml``).
    """
    spec = load_warehouse()
    if sensor is not None:
        if sensor not in SENSOR_KINDS:
            raise InputError(f"sensor must be one of {', '.join(SENSOR_KINDS)}, got {sensor!r}.")
        spec = dataclasses.replace(spec, sensor_kind=sensor)
    if sensor_noise is None:
        return spec
    if spec.sensor_kind != "scanner":
        raise InputError(
            "sensor_noise sets the idealised scanner's range noise; pass sensor='scanner' "
            "(--sensor scanner) with it, or leave it out for the camera (worlds/camera.yaml)."
        )
    return dataclasses.replace(spec, sensor_noise=float(sensor_noise))
