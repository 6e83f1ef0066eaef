"""Which LCM channels the dashboard listens to, their names from hw_config, and buffer sizes."""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from runtime.bus import DEFAULT_URL
from runtime.config import HW_CONFIG_DIR, load_profile, load_yaml
from runtime.config_types import Profile

#: Buffer size (messages) per channel key: about 4 s at each channel's nominal rate, and
#: only a handful for the large messages (depth frames, maps).
CAPACITY: dict[str, int] = {
    "state": 8192,
    "network_state": 2048,
    "torque": 8192,
    "applied_input": 8192,
    "plan": 2048,
    "depth": 256,  # headers only (see KEEP_BYTES)
    "elevation_map": 32,
    "footholds": 128,
    "mpfc_debug": 2048,
    "osc_debug": 8192,
    "timing": 2048,
    "ground_truth": 8192,
    "supervisor_status": 64,
}


#: Channel keys whose messages are cut to their first bytes on arrival: the dashboard reads
#: only the header and the fixed fields after it (a depth image is never drawn).
KEEP_BYTES: dict[str, int] = {"depth": 1024}


@dataclass(frozen=True)
class Channels:
    """LCM channel names by role (the keys of hw_config/channels.yaml)."""

    state: str = "CASSIE_STATE"
    network_state: str = "NETWORK_CASSIE_STATE"
    torque: str = "OSC_TORQUE"
    applied_input: str = "CASSIE_INPUT"
    plan: str = "NETWORK_MPFC_PLAN"
    depth: str = "DEPTH"
    elevation_map: str = "ELEVATION_MAP"
    footholds: str = "FOOTHOLDS"
    mpfc_debug: str = "MPFC_DEBUG"
    osc_debug: str = "OSC_DEBUG"
    timing: str = "TIMING"
    ground_truth: str = "GROUND_TRUTH"
    supervisor_status: str = "SUPERVISOR_STATUS"

    @classmethod
    def from_names(cls, names: dict[str, str]) -> Channels:
        """Defaults overridden by ``names`` (key -> channel); unknown keys are ignored."""
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in names.items() if k in known})

    def by_key(self) -> dict[str, str]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def keep_bytes(self) -> dict[str, int]:
        """Channel name -> bytes kept per message, for the channels in ``KEEP_BYTES``."""
        return {getattr(self, key): n for key, n in KEEP_BYTES.items()}

    def capacities(self, scale: float = 1.0) -> dict[str, int]:
        """Channel name -> buffer capacity (``scale`` multiplies the defaults)."""
        return {
            name: max(1, int(CAPACITY[key] * scale)) for key, name in self.by_key().items()
        }


@dataclass(frozen=True)
class Setup:
    """What the dashboard needs from the configuration."""

    lcm_url: str
    channels: Channels
    profile: Profile | None


def default_profile_path() -> Path | None:
    """hw_config/sim.yaml when it exists (the usual stack), else None."""
    p = HW_CONFIG_DIR / "sim.yaml"
    return p if p.exists() else None


def resolve_setup(profile: str | None) -> Setup:
    """Channel names and LCM URL from a launch profile, or from hw_config's defaults.

    Without a profile, names come from hw_config/channels.yaml and the URL from
    ``CASSIE_LCM_URL`` or hw_config/hosts.yaml (``lcm.url``).
    """
    spec = profile or default_profile_path()
    if spec:
        prof = load_profile(str(spec))
        names = {k: c.name for k, c in prof.channels.items() if not c.is_udp}
        names["timing"] = prof.timing_channel
        names["supervisor_status"] = prof.status_channel
        return Setup(prof.lcm_url, Channels.from_names(names), prof)
    names = {}
    ch_file = HW_CONFIG_DIR / "channels.yaml"
    if ch_file.exists():
        table: Any = load_yaml(ch_file).get("channels") or {}
        names = {str(k): v for k, v in table.items() if isinstance(v, str)}
    url = os.environ.get("CASSIE_LCM_URL")
    hosts = HW_CONFIG_DIR / "hosts.yaml"
    if not url and hosts.exists():
        url = (load_yaml(hosts).get("lcm") or {}).get("url")
    return Setup(str(url or DEFAULT_URL), Channels.from_names(names), None)
