"""MPFC: Model Predictive Footstep Control (Acosta & Posa), the algorithm without LCM.

Public API: `MpfcParams` (Table V, from hw_config/gains/mpfc.yaml),
`MpfcSolver(params).solve(...) -> MpfcSolution` over a list of `runtime.geometry.Foothold`.
See `solver.py` for frames and timing.
"""

from processes.mpfc.params import MpfcParams
from processes.mpfc.solver import MpfcSolution, MpfcSolver

__all__ = ["MpfcParams", "MpfcSolution", "MpfcSolver"]
