"""Thread counts of the model fits: one thread for small fits, and a temporary torch limit.

GP fits on a few hundred samples run many small matrix operations. On every such operation
torch's OpenMP pool and the BLAS pools wake their worker threads and wait for the slowest,
which costs more than the arithmetic it shares out; on a busy machine a worker that is not
scheduled stalls the others for a whole time slice, and the waiting threads spin meanwhile.
`fit_threads` therefore runs a fit on one thread up to `ONE_THREAD_MAX_ROWS` rows (20,000;
see its measurement) and with torch's current count above; the public fits of `probaff.models`
(`fit_em`, `fit_em_path`, `fit_svi`, `fit_transition`, `ClusteredGPModel.fit`,
`GPExpert.fit`, `SparseGPExpert.fit` and the scikit-learn estimator's `fit` and `predict`)
enter it through the decorator `threads_by_rows`.

The choice can be overridden: `set_fit_threads` (``probaff.set_fit_threads``) sets the
number of threads of every fit from code, and the environment variable
``PROBAFF_FIT_THREADS`` (a positive integer, or ``auto``) does so for a whole process. The
automatic choice never raises torch's count, so a program that called
``torch.set_num_threads(1)`` keeps one thread. A fit inside another fit, or inside a
`limit_threads` block, never runs on more threads than that block, whatever the setting.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import torch
from threadpoolctl import ThreadpoolController

from probaff._checks import check_count
from probaff.errors import InputError

__all__ = [
    "FIT_THREADS_ENV",
    "ONE_THREAD_MAX_ROWS",
    "fit_threads",
    "fit_threads_setting",
    "limit_threads",
    "rows_of",
    "set_fit_threads",
    "threads_by_rows",
    "threads_for_rows",
]

F = TypeVar("F", bound=Callable[..., Any])

ONE_THREAD_MAX_ROWS = 20_000
"""Fits on at most this many training rows run on one thread (torch and BLAS).

Measured on a 2-core virtual machine (AMD EPYC, torch 2.13 with OpenMP and MKL) shared with
other jobs (one-minute load average 2 to 10 besides the fit): `MixtureOfGPExpertsRegressor`
(M = 2; one EM start, no split-merge, 2 EM iterations, 20 first L-BFGS iterations) fitted on
`probaff.models.synthetic.regime_features` (D = 16, E = 1) and predicting 200 rows, with
``benchmarks/mixture_threads.py`` (N up to 5,000) and the same fit alone (10,000 and 20,000);
wall and CPU seconds, one thread against torch's pool of two, the machine as it was
("quiet") or with one busy-loop process beside the fit ("busy"):

======  =====  ======================  =======================
N       load   one thread: wall, CPU   pool of two: wall, CPU
======  =====  ======================  =======================
100     quiet  0.4, 0.4                1.7, 3.3
500     quiet  2.0, 2.0                8.9, 10.6
2,000   quiet  10.2, 10.0              78, 89
5,000   quiet  12.0, 11.7              225, 206
10,000  quiet  12.5, 12.5              18.7, 37.2
20,000  quiet  15.4, 15.4              272, 247
100     busy   0.7, 0.4                35, 24
500     busy   3.1, 1.5                52, 37
2,000   busy   78, 11.7                350, 147
======  =====  ======================  =======================

scikit-learn's diabetes data (442 x 10), the estimator's defaults, 5-fold CV: 19.7 CPU
seconds on one thread, 676 with the pool. The pool paid at no size: a fit is mostly small
products (the search above `EMOptions.search_rows` runs on 1,000 rows and sparse experts
choose their hyperparameters on 2,048), each a parallel region whose threads wait for one
another, for a whole time slice when the machine is busy. Above 20,000 rows, not measured
here, the products over every row grow and torch's count is kept for a pool to share them;
a nested fit on fewer rows (the search's `fit_em_path`) still runs on one thread.
"""

FIT_THREADS_ENV = "PROBAFF_FIT_THREADS"
"""Environment variable that sets the thread count of every fit: an integer >= 1 or
``auto`` (the default when unset or empty); `set_fit_threads` takes precedence."""

_setting: int | None = None
_local = threading.local()
_pools: tuple[int, ThreadpoolController] | None = None


def set_fit_threads(n: int | None) -> None:
    """Set the number of torch and BLAS threads every model fit of probaff runs with.

    Args:
        n: Threads of every fit (a positive integer), or None for the default: the
            ``PROBAFF_FIT_THREADS`` environment variable when set, else the automatic
            choice (one thread up to `ONE_THREAD_MAX_ROWS` training rows, torch's current
            count above).

    Raises:
        InputError: If `n` is neither None nor a positive integer.
    """
    global _setting
    if n is None:
        _setting = None
        return
    try:
        _setting = check_count("n", n)
    except InputError:
        raise InputError(
            f"set_fit_threads: n must be a positive integer (threads) or None (automatic), "
            f"got {n!r}."
        ) from None


def fit_threads_setting() -> int | None:
    """The thread count set for every fit, or None when it is chosen automatically.

    Returns:
        The count of `set_fit_threads`, else that of ``PROBAFF_FIT_THREADS``, else None.

    Raises:
        InputError: If ``PROBAFF_FIT_THREADS`` is neither ``auto`` nor a positive integer.
    """
    if _setting is not None:
        return _setting
    text = os.environ.get(FIT_THREADS_ENV, "").strip()
    if text.lower() in ("", "auto"):
        return None
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise InputError(
            f"{FIT_THREADS_ENV}={text!r} must be a positive integer or 'auto'; fix or unset it."
        )
    return value


def threads_for_rows(n_rows: int) -> int:
    """The threads a fit on `n_rows` training rows runs with, outside any limited block.

    Args:
        n_rows: Training rows of the fit (an integer >= 0).

    Returns:
        `fit_threads_setting` when set; else 1 up to `ONE_THREAD_MAX_ROWS` rows and torch's
        current count above it, but never more than that count.

    Raises:
        InputError: If `n_rows` is not an integer >= 0, or as `fit_threads_setting`.
    """
    n_rows = check_count("n_rows", n_rows, minimum=0)
    setting = fit_threads_setting()
    if setting is not None:
        return setting
    current = torch.get_num_threads()
    return 1 if n_rows <= ONE_THREAD_MAX_ROWS else current


def rows_of(x: Any) -> int:
    """The number of rows of an array-like `x`, or 0 when it has none (the fit checks it).

    Args:
        x: A tensor, array, data frame, sequence or anything else.

    Returns:
        ``x.shape[0]`` or ``len(x)``; 0 for a scalar or an object without a length.
    """
    shape = getattr(x, "shape", None)
    if shape is not None:
        with contextlib.suppress(TypeError, IndexError, ValueError):
            return max(int(shape[0]), 0)
        return 0
    try:
        return len(x)
    except TypeError:
        return 0


def _depth() -> int:
    return int(getattr(_local, "depth", 0))


def _controller() -> ThreadpoolController:
    """The BLAS and OpenMP libraries loaded, as threadpoolctl sees them.

    Finding them scans every loaded library (milliseconds), so the view is kept until a
    module is imported (which may load another library).
    """
    global _pools
    key = len(sys.modules)
    if _pools is None or _pools[0] != key:
        _pools = (key, ThreadpoolController())
    return _pools[1]


@contextlib.contextmanager
def _limited(n: int | None) -> Iterator[None]:
    """A block marked as limited; with `n`, torch, BLAS and OpenMP at `n` threads."""
    previous = torch.get_num_threads()
    _local.depth = _depth() + 1
    try:
        with contextlib.ExitStack() as stack:
            if n is not None:
                stack.enter_context(_controller().limit(limits=n))
                torch.set_num_threads(n)
                stack.callback(torch.set_num_threads, previous)
            yield
    finally:
        _local.depth -= 1


@contextlib.contextmanager
def fit_threads(n_rows: int) -> Iterator[int]:
    """Run a fit on `n_rows` training rows with the threads that pay (`threads_for_rows`).

    Torch's intra-op threads and the BLAS and OpenMP pools (through threadpoolctl) are set
    to that count and restored after. Inside another `fit_threads` or a `limit_threads`
    block the count is never raised above the block's; there, a fit that wants what it
    already has changes nothing.

    Args:
        n_rows: Training rows of the fit (an integer >= 0).

    Yields:
        The number of torch threads inside the block.

    Raises:
        InputError: If `n_rows` is not an integer >= 0, or as `fit_threads_setting`.
    """
    want = threads_for_rows(n_rows)
    current = torch.get_num_threads()
    if _depth() > 0 and want >= current:
        with _limited(None):
            yield current
    else:
        with _limited(want):
            yield want


def threads_by_rows(arg: str = "X") -> Callable[[F], F]:
    """Decorate a fit so that it runs inside `fit_threads` sized by its argument `arg`.

    Args:
        arg: The parameter holding the training rows (counted by `rows_of`).

    Returns:
        The decorator; the decorated function keeps its name, signature and docstring.
    """

    def decorate(fn: F) -> F:
        signature = inspect.signature(fn)
        if arg not in signature.parameters:
            raise TypeError(f"{fn.__qualname__} has no parameter {arg!r} to count rows of.")

        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            try:
                bound = signature.bind(*args, **kwargs)
            except TypeError:
                return fn(*args, **kwargs)  # Python's own message for a wrong call
            with fit_threads(rows_of(bound.arguments.get(arg))):
                return fn(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate


@contextlib.contextmanager
def limit_threads(n: int) -> Iterator[None]:
    """Run the block on `n` threads: torch's intra-op pool and the BLAS and OpenMP pools.

    Torch's count (`torch.set_num_threads`) and the pools' (through threadpoolctl) are
    restored after. The pools matter as much as torch's: the small solves and products of
    scikit-learn's Gaussian mixtures and scipy's L-BFGS inside a fit run on the BLAS pool,
    and with torch alone at one thread a small EM fit (`fit_em`, 90 rows, M = 3) cost 3 times
    the CPU time on a 2-core machine shared with other jobs.

    The block counts as limited: a fit inside it (`fit_threads`) never runs on more than
    `n` threads.

    Args:
        n: Number of intra-op threads (a positive integer).

    Raises:
        InputError: If `n` is not a positive integer.
    """
    n = check_count("n", n)
    with _limited(n):
        yield
