"""Test helpers: the scripted sim loop (from ``tools.testbed.estimator_motions``) and live
runner configs for nodes bound to real UDP ports and LCM channels."""

from __future__ import annotations

from typing import Any

from tools.benchmarks.common import free_udp_port  # noqa: F401  (the one helper, for the tests)
from tools.testbed.estimator_motions import (  # noqa: F401  (re-exported for the tests)
    MOTIONS,
    LoopRecord,
    ScriptedController,
    errors,
    pd_torque,
    run_loop,
    sim_settings,
    targets,
)


def live_configs(name: str, module: str, lcm_url: str, inputs: dict[str, Any],
                 outputs: dict[str, Any]) -> tuple[Any, Any]:
    """A ProcessConfig and Profile for running one node with ``LiveRunner`` in a test.

    ``inputs``/``outputs`` map role -> LCM channel name or ("udp", port); the gains file is
    ``hw_config/gains/NAME.yaml`` when there is one."""
    from pathlib import Path

    from runtime.config_types import ChannelConfig, ProcessConfig, Profile

    hw = Path(__file__).resolve().parents[2] / "hw_config"

    def ch(role: str, v: Any) -> ChannelConfig:
        if isinstance(v, tuple):
            return ChannelConfig(role, f"udp:127.0.0.1:{v[1]}", udp=("127.0.0.1", int(v[1])))
        return ChannelConfig(role, v)

    proc = ProcessConfig(
        name=name, host="nuc", module=module, source_file=hw / "processes.yaml",
        rate_hz=2000.0, deadline_ms=1.0,
        inputs={r: ch(r, v) for r, v in inputs.items()},
        outputs={r: ch(r, v) for r, v in outputs.items()},
        gains_file=gains if (gains := hw / "gains" / f"{name}.yaml").is_file() else None,
    )
    profile = Profile(name="test", path=hw / "test.yaml", hw_config_dir=hw, mode="realtime",
                      lcm_url=lcm_url, hosts={}, channels={}, processes={}, launch=())
    return proc, profile
