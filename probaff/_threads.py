"""Temporary limit on torch's intra-op threads.

GP fits on a few hundred samples run many small matrix operations; on machines where
waking worker threads is slow (e.g. small virtual machines), one thread is faster.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

from probaff._checks import check_count

__all__ = ["torch_threads"]


@contextlib.contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run the block with `torch.set_num_threads(n)`, restoring the previous count after.

    Args:
        n: Number of intra-op threads (a positive integer).

    Raises:
        InputError: If `n` is not a positive integer.
    """
    n = check_count("n", n)
    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
