"""runtime.params: a Literal matches a value of its own type only (YAML's bare ``off`` is
false, and 0 must not pass for it), its allowed values are a field's ``choices`` when it has
them; a block that takes no keys says so when given one."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import pytest

from runtime.errors import ConfigError
from runtime.params import read, spec

Render = Literal["auto", "off", False]


@dataclass(frozen=True)
class Camera:
    render: Render | None = spec(None, choices=("auto", "off"))
    level: Literal[1, 2] = 1


@dataclass(frozen=True)
class Nothing:
    """No keys."""


def test_a_literal_matches_its_own_values_of_their_own_types() -> None:
    assert read(Camera, {"render": False}, "f.yaml").render is False
    assert read(Camera, {"render": "off", "level": 2}, "f.yaml") == Camera("off", 2)
    for data, problem in (({"render": 0}, "render: 0 is not one of"),
                          ({"level": True}, "level: True is not one of"),
                          ({"level": 1.0}, "level: 1.0 is not one of")):
        with pytest.raises(ConfigError, match=problem):
            read(Camera, data, "f.yaml")


def test_a_literal_names_its_fields_choices_as_allowed() -> None:
    with pytest.raises(ConfigError) as err:
        read(Camera, {"render": "on"}, "f.yaml")
    assert str(err.value) == ("f.yaml: render: 'on' is not one of the allowed values "
                              "(allowed: auto, off)")


def test_a_block_of_no_keys_says_so() -> None:
    with pytest.raises(ConfigError) as err:
        read(Nothing, {"x": 1}, "f.yaml", key="processes.p.params")
    assert str(err.value) == ("f.yaml: processes.p.params.x: unknown key "
                              "(allowed: none: it takes no keys)")
