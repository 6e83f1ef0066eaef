"""Operational space controller (Acosta & Posa, Sections III-E and V), with no LCM inside.

Public API: ``OscController.update(t_s, q, v, plan, command) -> (torques (10,), OscDebug)``,
``OscParams.from_gains(runtime.params.load(OscGains, path))``; the LCM shell is
``processes.osc.process.make_node``.
"""

from .controller import SAFE, STANDING, WALKING, OscController, OscDebug
from .tasks import OscGains, OscParams

__all__ = ["SAFE", "STANDING", "WALKING", "OscController", "OscDebug", "OscGains", "OscParams"]
