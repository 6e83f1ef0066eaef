"""A deputy (runtime.deputy) takes orders only with the hosts' shared key, says why it cannot
serve a launch (a missing profile, another instance) in its status, and the launch's secrets
follow from the key and the launch's name on every host alike."""

from __future__ import annotations

import stat
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from lcmtypes import deputy_orders_t, deputy_status_t
from runtime.bus import Bus
from runtime.deputy import Deputy, deputy_key, launch_secrets
from runtime.errors import ConfigError
from runtime.pairing import sign_message

KEY = bytes(range(32))


def _orders(profile: str, instance: int = 0, launch: str = "00aa11bb22cc33dd") -> deputy_orders_t:
    msg = deputy_orders_t()
    msg.launch, msg.profile, msg.instance, msg.log_dir = launch, profile, instance, "/nonexistent"
    msg.process, msg.host, msg.run, msg.run_id = ["sim"], ["target_pc"], [True], [1]
    msg.num_processes = 1
    return msg


@pytest.fixture
def deputy(lcm_url: str) -> Iterator[Deputy]:
    d = Deputy("target_pc", lcm_url, "DEPUTY_ORDERS", "DEPUTY_STATUS", KEY)
    yield d
    d.bus.close()


def test_unsigned_or_wrongly_signed_orders_are_refused_and_counted(deputy: Deputy) -> None:
    msg = _orders("hw_config/sim.yaml")
    msg.auth_len, msg.auth = 0, b""
    deputy._on_orders("DEPUTY_ORDERS", msg.encode())
    deputy._on_orders("DEPUTY_ORDERS", sign_message(_orders("hw_config/sim.yaml"), b"x" * 32))
    deputy._on_orders("DEPUTY_ORDERS", b"\x00garbage")
    assert deputy.refused == 3
    assert deputy.launch == "" and deputy.sup is None  # nothing was started or loaded


def test_a_launch_it_cannot_serve_is_said_in_its_status(deputy: Deputy, lcm_url: str) -> None:
    listener = Bus(lcm_url, source="test")
    got: list[deputy_status_t] = []
    listener.subscribe_raw("DEPUTY_STATUS", lambda _c, d: got.append(deputy_status_t.decode(d)))
    deputy._on_orders("DEPUTY_ORDERS", sign_message(_orders("hw_config/no_such.yaml"), KEY))
    assert "no profile hw_config/no_such.yaml on this host" in deputy.error
    deputy._publish()
    deputy._on_orders("DEPUTY_ORDERS", sign_message(
        _orders("hw_config/sim.yaml", instance=3, launch="ffee"), KEY))
    assert "start it with --instance 3" in deputy.error
    deputy._publish()
    t0 = time.monotonic()
    while len(got) < 2 and time.monotonic() - t0 < 2.0:
        listener.poll_every(0.02)
    listener.close()
    assert [m.error.split(":")[0] for m in got] == [
        "no profile hw_config/no_such.yaml on this host (looked at "
        f"{Path(__file__).resolve().parents[2] / 'hw_config' / 'no_such.yaml'})",
        "the launch runs instance 3, this deputy instance 0"]
    assert got[0].host == "target_pc" and got[1].launch == "ffee"


def test_the_launch_secrets_are_the_same_for_one_launch_and_differ_between_launches() -> None:
    a, b = launch_secrets(KEY, "launch-a"), launch_secrets(KEY, "launch-b")
    assert a == launch_secrets(KEY, "launch-a") and a != b
    for token, timing_key in (a, b):
        assert 0 < token < 1 << 32 and token & 1 and len(timing_key) == 32
    assert launch_secrets(b"y" * 32, "launch-a") != a  # another key file, another launch


def test_the_key_file_is_made_private_once_and_a_bad_one_is_a_clear_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "cfg" / "deputy.key"
    monkeypatch.setenv("CASSIE_DEPUTY_KEY_FILE", str(path))
    with pytest.raises(ConfigError, match="copy it to this host"):
        deputy_key(create=False)
    key = deputy_key()
    assert len(key) == 32 and deputy_key() == key
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    path.write_text("not hex\n")
    with pytest.raises(ConfigError, match="is not a key"):
        deputy_key()
