"""MPFC: Model Predictive Footstep Control (Acosta & Posa), the algorithm without LCM.

Public API: `MpfcParams` (Table V, from hw_config/gains/mpfc.yaml), `Foothold`,
`MpfcSolver(params).solve(...) -> MpfcSolution`. See `solver.py` for frames and timing.
"""

from processes.mpfc.footholds import Foothold
from processes.mpfc.params import MpfcParams
from processes.mpfc.solver import MpfcSolution, MpfcSolver

__all__ = ["Foothold", "MpfcParams", "MpfcSolution", "MpfcSolver"]
