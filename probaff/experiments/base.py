"""What every study shares: its run settings (`StudyConfig`) and its run (`StudyRun`).

A study is one folder of `probaff.experiments` whose package names ``Config`` (a
`StudyConfig`), ``SMOKE`` (its smoke sizes) and ``run(config)``. Its `run` opens a `StudyRun`,
the skeleton every study follows:

    study = StudyRun(config)                  # validates the config once
    tag = study.config.tag(version=1)         # fingerprint of what shapes a result
    records = study.tasks(fn, [(f"key.{tag}", args), ...], desc="...")  # resumable, on Dask
    study.table("results.csv", rows)          # tables, figures, summary.md: atomic writes
    study.figure(plot(rows, study.out / "results.png"))
    study.summary(["# My study", "", markdown_table(rows, columns)])
    return {"rows": rows, "files": study.files}

Each task's result lands in ``out/tasks/KEY.json`` as soon as it finishes
(`probaff.eval.tasks.run_tasks`), so a killed run redoes only the missing tasks, and a key
carries the fingerprint of every setting that shapes it, so results of other settings are
never mixed in.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar, Generic, TypeVar

from probaff._checks import check_count, check_output_dir
from probaff._dask import check_batch
from probaff._io import atomic_write_text
from probaff.data import GenerateConfig, generate
from probaff.errors import InputError
from probaff.eval.fingerprint import settings_fingerprint
from probaff.eval.tables import write_csv
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.experiments.config_cli import field_settings, rebuild, with_smoke
from probaff.sim.world_files import worlds_dir

__all__ = ["StudyConfig", "StudyRun", "check_planners", "world_digest"]

C = TypeVar("C", bound="StudyConfig")


def check_planners(planners: Sequence[str], known: Collection[str]) -> None:
    """Check a study's ``planners`` field: at least one, each of them among `known` (names).

    Raises:
        InputError: Naming the unknown planners (or the empty choice) and the known ones.
    """
    unknown = [p for p in planners if p not in known]
    if unknown or not planners:
        raise InputError(
            f"planners: unknown or no planners {unknown or list(planners)}; choose from "
            f"{list(known)}."
        )


def world_digest(names: Sequence[str], length: int = 6) -> str:
    """Short hash of the world files `names` (paths under `probaff.sim.world_files.worlds_dir`).

    The task, scene, world and catalogue files shape a study's results as much as its config
    does, so a tag that includes them never lets an edited file reuse a stored result.
    """
    digest = hashlib.sha256()
    for name in names:
        digest.update((worlds_dir() / name).read_bytes())
    return digest.hexdigest()[:length]


@dataclass(frozen=True, kw_only=True)
class StudyConfig:
    """The settings every study has: where and how it runs, and its seed.

    A study's config subclasses it (``@dataclass(frozen=True, kw_only=True)``) with the
    settings that shape its results, overrides `check` to validate them, and sets `SMOKE`.

    Attributes:
        out: Output folder (datasets, per-task results, tables, figures).
        seed: Seed of everything the study draws (an integer >= 0).
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        progress: Show progress bars.
    """

    out: str = "results"
    seed: int = 0
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True

    RUN_ONLY: ClassVar[frozenset[str]] = frozenset({"out", "workers", "scheduler", "progress"})
    """Fields that say where and how the study runs, not what it computes."""

    SMOKE: ClassVar[Mapping[str, Any]] = MappingProxyType({})
    """Field values of a tiny run that checks the whole pipeline (see `smoke`)."""

    SHORTHANDS: ClassVar[Mapping[str, tuple[str, Any, str]]] = MappingProxyType({})
    """Extra command-line flags: flag -> (field, the value it sets, help text)."""

    TRAILING_FLAGS: ClassVar[tuple[str, ...]] = ("workers", "scheduler", "progress")
    """Fields whose flags are listed last."""

    @classmethod
    def smoke(cls: type[C], **fields: Any) -> C:
        """The smoke-sized config: `SMOKE` for every field not in `fields`.

        Args:
            **fields: Field values (e.g. ``out``) that the smoke sizes never replace.
        """
        return with_smoke(cls(**fields), cls.SMOKE, fields)

    def check(self) -> Mapping[str, Any]:
        """Check the study's own settings (a study overrides it).

        Returns:
            Fields whose values are normalised (e.g. counts as builtin ints).

        Raises:
            InputError: For a setting out of range.
        """
        return {}

    def validate(self: C) -> C:
        """Check every setting and return the config with its counts as builtin ints.

        Returns:
            An equal config whose ``seed``, ``workers`` and the fields `check` normalises
            are builtin types (``numpy.int64(3)`` or ``3.0`` become ``3``), so that its
            fingerprint does not depend on how a count was typed.

        Raises:
            InputError: For a setting out of range, a bad scheduler address or an output
                folder that cannot be made.
        """
        seed = check_count("seed", self.seed, minimum=0)
        normal = dict(self.check())
        workers, _ = check_batch(self.workers, self.scheduler)
        check_output_dir("out", self.out)
        return rebuild(self, seed=seed, workers=workers, **normal)

    def tag(
        self,
        *,
        version: int,
        only: Iterable[str] | None = None,
        exclude: Iterable[str] = (),
        world: Sequence[str] = (),
        length: int = 10,
    ) -> str:
        """Fingerprint of the settings that shape a result, for its task keys and files.

        Args:
            version: Version of the code that computes the results; bump it when a change
                of that code changes results.
            only: The fields that shape it; None for every field but `RUN_ONLY` and
                `exclude`. Each field counts by its settings (`field_settings`: fit
                options by their flags' names).
            exclude: Further fields that do not shape it.
            world: World files it reads (`world_digest`), appended to the tag.
            length: Hexadecimal characters of the fields' part.

        Returns:
            The settings' hash (`settings_fingerprint`), then the world files' if any.
        """
        fields = dataclasses.fields(self)
        names = {f.name for f in fields}
        skip = names - set(only) if only is not None else {*self.RUN_ONLY, *exclude}
        values = {
            k: v for f in fields if f.name not in skip for k, v in field_settings(self, f).items()
        }
        tag = settings_fingerprint(values, version=version, length=length)
        return tag + world_digest(world) if world else tag


class StudyRun(Generic[C]):
    """One run of a study: its validated config, output folder and the files it wrote.

    Args:
        config: The study's settings; validated here (`StudyConfig.validate`).
        kind: The study's config class, which `config` must be an instance of.

    Attributes:
        config: The validated config.
        out: The output folder.
        files: Paths written so far, in order.

    Raises:
        InputError: For a `config` that is not a `kind`, or one that does not validate.
    """

    def __init__(self, config: C, kind: type[StudyConfig] = StudyConfig) -> None:
        if not isinstance(config, kind):
            raise InputError(
                f"config must be a {kind.__name__} (e.g. {kind.__name__}() or "
                f"{kind.__name__}.smoke()), got {type(config).__name__}."
            )
        self.config: C = config.validate()
        self.out = Path(self.config.out)
        self.files: list[str] = []

    def tasks(
        self,
        fn: Callable[..., dict[str, Any]],
        tasks: Sequence[tuple[str, tuple[Any, ...]]],
        *,
        desc: str,
        shared: Mapping[str, Any] | None = None,
        folder: str = "tasks",
        measured: Sequence[str] = (),
    ) -> list[dict[str, Any]]:
        """Run the tasks whose results are not saved under ``out/folder`` yet; all results.

        Args:
            fn: ``fn(*args, **shared) -> dict``, a module-level function (Dask workers
                import it).
            tasks: ``(key, args)`` pairs with unique keys, in the order they should start.
            desc: Label of the progress bar.
            shared: Keyword arguments every task receives, sent to each worker once.
            folder: The result store's folder under the output folder.
            measured: Fields of a result that measure this run rather than compute a
                result (wall-clock times). They are kept in ``out/timings/folder/KEY.json``,
                apart from the result files, which are then the same byte for byte in every
                run of the same settings (`ResultStore`).

        Returns:
            The results of all tasks, in the order of `tasks`, measured fields included.
        """
        c = self.config
        store = ResultStore(
            self.out / folder, measured=measured, measured_root=self.out / "timings" / folder
        )
        return run_tasks(
            fn,
            tasks,
            store,
            workers=c.workers,
            scheduler=c.scheduler,
            progress=c.progress,
            desc=desc,
            shared=shared,
        )

    def dataset(self, config: GenerateConfig, name: str, *, local: bool = False) -> Any:
        """Generate (or resume) a dataset in ``out/data/name``.

        Args:
            config: What to generate.
            name: The dataset's folder under ``out/data``.
            local: Generate in this process (else with the study's workers or scheduler).

        Returns:
            The dataset of the scene's kind (`PushDataset`, `SkillDataset`, ...).
        """
        c = self.config
        return generate(
            config,
            self.out / "data" / name,
            workers=0 if local else c.workers,
            scheduler=None if local else c.scheduler,
            resume=True,
            progress=c.progress,
        )

    def table(self, name: str, rows: Sequence[dict[str, Any]]) -> str:
        """Write `rows` to ``out/name`` as CSV (list-valued columns dropped); its path."""
        path = write_csv(self.out / name, rows)
        self.files.append(path)
        return path

    def figure(self, path: str | Path) -> str:
        """Record a figure written to `path`; its path as a string."""
        self.files.append(str(path))
        return str(path)

    def write(self, name: str, text: str) -> str:
        """Write `text` to ``out/name`` atomically; its path."""
        path = self.out / name
        atomic_write_text(path, text)
        self.files.append(str(path))
        return str(path)

    def summary(self, lines: Sequence[str] | str) -> str:
        """Write the Markdown summary (lines joined by newlines) to ``out/summary.md``."""
        return self.write("summary.md", lines if isinstance(lines, str) else "\n".join(lines))
