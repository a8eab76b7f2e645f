"""Device checks of the model tests that can fail on a machine with only a CPU.

On a CPU-only machine, "the output is on the device of the inputs" compares the CPU with the
CPU: a tensor made without ``device=`` lands on the CPU too and the check passes. Two tools make
such a slip visible there:

- `elsewhere` runs code with torch's default device set to ``meta``: a tensor made without an
  explicit device becomes a meta tensor, which `assert_on_device` then finds among the outputs
  (or which fails as soon as it meets the real inputs, or has its data read).
- `assert_on_device` walks an output (tensors, distributions and their parameters, dataclasses,
  named tuples, sequences, mappings, modules' parameters and buffers) and compares the whole
  device, index included, of every tensor it finds.
"""

import contextlib
import dataclasses
from collections.abc import Iterator, Mapping
from typing import Any

import pytest
import torch

# every device the device tests run on; CUDA is a visible skip where this machine has none
NO_CUDA = "no CUDA device on this machine: the CPU runs alone (the CUDA case is skipped)"
DEVICES = [
    "cpu",
    pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(), reason=NO_CUDA)),
]


def tensors_in(
    obj: Any, where: str = "output", _seen: set[int] | None = None
) -> Iterator[tuple[str, torch.Tensor]]:
    """Every tensor reachable from `obj`, with the path that reaches it."""
    seen = set() if _seen is None else _seen
    if id(obj) in seen or obj is None or isinstance(obj, (str, bytes, int, float, bool)):
        return
    seen.add(id(obj))
    if isinstance(obj, torch.Tensor):
        yield where, obj
    elif isinstance(obj, torch.nn.Module):
        for name, t in obj.named_parameters():
            yield f"{where}.{name}", t
        for name, t in obj.named_buffers():
            yield f"{where}.{name}", t
    elif isinstance(obj, torch.distributions.Distribution):
        # the parameters a distribution was built with and the ones it derived (lazy ones too)
        for name, value in vars(obj).items():
            yield from tensors_in(value, f"{where}.{name}", seen)
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for field in dataclasses.fields(obj):
            yield from tensors_in(getattr(obj, field.name), f"{where}.{field.name}", seen)
    elif isinstance(obj, Mapping):
        for key, value in obj.items():
            yield from tensors_in(value, f"{where}[{key!r}]", seen)
    elif isinstance(obj, (tuple, list)):
        names = getattr(obj, "_fields", None)  # a named tuple names its parts
        for i, value in enumerate(obj):
            yield from tensors_in(value, f"{where}.{names[i]}" if names else f"{where}[{i}]", seen)
    elif hasattr(obj, "__dict__"):  # a plain result object
        for name, value in vars(obj).items():
            yield from tensors_in(value, f"{where}.{name}", seen)


def assert_on_device(obj: Any, device: torch.device | str, where: str = "output") -> int:
    """Assert that every tensor in `obj` lives on `device`; the number of tensors checked.

    The device is compared whole (``cuda:0`` is not ``cuda:1``); a bare ``"cuda"`` means the
    current CUDA device. At least one tensor must be found, so an output whose tensors the walk
    cannot reach fails instead of passing empty.
    """
    want = torch.device(device)
    if want.type == "cuda" and want.index is None:
        want = torch.device("cuda", torch.cuda.current_device())
    found = list(tensors_in(obj, where))
    assert found, f"{where}: no tensor found to check"
    wrong = [f"{path} on {t.device}" for path, t in found if t.device != want]
    assert not wrong, f"not on {want}: " + ", ".join(wrong)
    return len(found)


@contextlib.contextmanager
def elsewhere() -> Iterator[None]:
    """Run with torch's default device set to ``meta``.

    Inputs keep their device; any tensor the code makes without naming a device goes to
    ``meta``, where it has no data, so the slip fails loudly or shows up in the outputs.
    """
    with torch.device("meta"):
        yield
