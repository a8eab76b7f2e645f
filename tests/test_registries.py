"""probaff._registry: one set of rules for every registry (models, worlds, dataset kinds)."""

from dataclasses import dataclass

import pytest

from probaff._registry import Registry
from probaff.data.kinds import dataset_kinds, register_dataset_kind, unregister_dataset_kind
from probaff.errors import InputError
from probaff.models import model_kinds, register_model_kind, unregister_model_kind
from probaff.sim.registry import register_world, unregister_world, world_kinds


@dataclass(frozen=True)
class Entry:
    name: str


def test_entries_keep_their_order_and_names_are_unique():
    reg = Registry("colour", Entry, "unregister_colour")
    red, blue = reg.add(Entry("red")), reg.add(Entry("blue"))
    assert reg.values() == [red, blue] and reg.names() == ["red", "blue"] and len(reg) == 2
    assert "red" in reg and "green" not in reg and list(reg) == ["red", "blue"]
    assert reg.get("blue") is blue
    with pytest.raises(InputError, match="colour 'red' is registered already; unregister_colour"):
        reg.add(Entry("red"))
    assert reg.remove("red") is red and reg.names() == ["blue"]
    reg.add(Entry("red"))  # a removed name is free again
    assert reg.names() == ["blue", "red"]


def test_unknown_names_and_wrong_classes_are_refused_by_name():
    reg = Registry("colour", Entry, "unregister_colour")
    reg.add(Entry("red"))
    with pytest.raises(InputError, match=r"unknown colour 'green'; registered: \['red'\]"):
        reg.get("green")
    with pytest.raises(InputError, match="colour 3 is not registered"):
        reg.remove(3)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="a colour must be a Entry, got str"):
        reg.add("red")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "entries, register, unregister",
    [
        (lambda: list(model_kinds().values()), register_model_kind, unregister_model_kind),
        (world_kinds, register_world, unregister_world),
        (dataset_kinds, register_dataset_kind, unregister_dataset_kind),
    ],
    ids=["models", "worlds", "dataset kinds"],
)
def test_every_registry_refuses_a_taken_name_and_restores(entries, register, unregister):
    """Each built-in entry: registering it again is refused; removed and re-added it is back."""
    before = entries()
    assert before, "the registry is empty"
    for entry in before:
        with pytest.raises(InputError, match="registered already"):
            register(entry)
    last = before[-1]
    assert unregister(last.name) is last
    try:
        assert last.name not in [e.name for e in entries()]
        with pytest.raises(InputError, match="not registered"):
            unregister(last.name)
    finally:
        register(last)
    assert [e.name for e in entries()] == [e.name for e in before]
