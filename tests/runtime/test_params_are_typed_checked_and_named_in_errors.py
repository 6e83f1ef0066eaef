"""runtime.params: the one mechanism for gains and params. Every key known, every value of
its type and range, and every error naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from runtime.errors import ConfigError
from runtime.params import read, spec


@dataclass(frozen=True)
class Swing:
    kp: float = spec(120.0, lo=0.0)
    mode: str = spec("ik", choices=("ik", "task"))


@dataclass(frozen=True)
class Gains:
    rate_hz: float = spec(lo=0.0, lo_open=True)  # required: no default
    steps: int = spec(2, lo=2, hi=4)
    on: bool = True
    weights: tuple[float, float, float] = (1.0, 2.0, 3.0)
    radii: tuple[float, ...] = ()
    swing: Swing = spec(default_factory=Swing)
    limit: float | None = None


F = "hw_config/gains/x.yaml"


def test_values_are_read_with_their_types_and_defaults() -> None:
    g = read(Gains, {"rate_hz": 500, "weights": [1, 2, 3.5], "radii": [0.1],
                     "swing": {"kp": 80}, "limit": None}, F)
    assert g == Gains(rate_hz=500.0, weights=(1.0, 2.0, 3.5), radii=(0.1,),
                      swing=Swing(kp=80.0))
    assert isinstance(g.rate_hz, float) and isinstance(g.steps, int)


@pytest.mark.parametrize(("data", "message"), [
    ({"rate_hz": 1, "rte_hz": 2}, "x.yaml: osc.rte_hz: unknown key (allowed: limit, on, "
                                  "radii, rate_hz, steps, swing, weights)"),
    ({}, "osc.rate_hz: is required (allowed: (0.0, inf])"),
    ({"rate_hz": 0}, "osc.rate_hz: out of range: 0 (allowed: (0.0, inf])"),
    ({"rate_hz": float("nan")}, "osc.rate_hz: out of range: nan"),
    ({"rate_hz": "fast"}, "osc.rate_hz: must be a number, got 'fast'"),
    ({"rate_hz": 1, "steps": 5}, "osc.steps: out of range: 5 (allowed: [2, 4])"),
    ({"rate_hz": 1, "steps": 2.5}, "osc.steps: must be an integer, got 2.5"),
    ({"rate_hz": 1, "on": 1}, "osc.on: must be true or false, got 1 (allowed: true, false)"),
    ({"rate_hz": 1, "weights": [1, 2]}, "osc.weights: must be a list of 3, got 2"),
    ({"rate_hz": 1, "radii": [0.1, "x"]}, "osc.radii[1]: must be a number, got 'x'"),
    ({"rate_hz": 1, "swing": {"kd": 1}}, "osc.swing.kd: unknown key (allowed: kp, mode)"),
    ({"rate_hz": 1, "swing": {"mode": "fk"}},
     "osc.swing.mode: 'fk' is not one of the allowed values (allowed: ik, task)"),
    ({"rate_hz": 1, "swing": 3}, "osc.swing: must be a mapping, got 3"),
    ({"rate_hz": 1, "limit": True}, "osc.limit: must be a number, got True"),
])
def test_a_bad_key_or_value_is_an_error_naming_file_key_and_allowed(data, message) -> None:
    with pytest.raises(ConfigError) as err:
        read(Gains, data, F, key="osc")
    assert message in str(err.value)
    assert str(err.value).startswith(F)


def test_a_gains_file_has_one_shape_top_level_values_and_variants_over_them(tmp_path) -> None:
    from runtime.params import load

    path = tmp_path / "g.yaml"
    path.write_text("rate_hz: 500\nswing: {kp: 80}\ndefault_variant: sim\nvariants:\n"
                    "  sim: {steps: 3, swing: {mode: task}}\n  hw: {rate_hz: 0}\n")
    assert load(Gains, path) == Gains(rate_hz=500.0, steps=3, swing=Swing(80.0, "task"))
    with pytest.raises(ConfigError, match=r"g.yaml: variants.hw.rate_hz: out of range: 0"):
        load(Gains, path, "hw")
    with pytest.raises(ConfigError, match=r"variants: no variant 'real' \(allowed: sim, hw\)"):
        load(Gains, path, "real")
    path.write_text("rate_hz: 5\nrate_hz: 6\n")
    with pytest.raises(ConfigError, match="rate_hz"):  # a key twice: never the last one silently
        load(Gains, path)
