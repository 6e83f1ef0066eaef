"""The literal mixed-integer form of a footstep planner's problem, with big-M foothold rows and
binaries: what the reference solvers (Gurobi, an exhaustive piqp enumeration:
``tools.testbed.gurobi_reference``) check the exact search against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MiqpData:
    """A planner's MIQP literally (the MPFC's (15), the DCM planner's (21)): min 0.5 v'Pv +
    q'v + const over continuous v and binary mu, with Aeq v = beq, G v + Gmu mu <= h, Smu mu
    = 1, lb <= v <= ub; N steps, M footholds (mu[n M + i]: step n on foothold i).

    MPFC: v = [x_0..x_N (4 each), p_1..p_N (3 each, 3D), u, T, s (4(N+1) slacks)]; ip, iu,
    iT index p_1, u and T in v.
    """

    P: np.ndarray
    q: np.ndarray
    const: float
    Aeq: np.ndarray
    beq: np.ndarray
    G: np.ndarray
    Gmu: np.ndarray
    h: np.ndarray
    Smu: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    N: int
    M: int
    ip: int  # index of p_1 in v
    iu: int
    iT: int
    t_nominal: float

    def fixed(self, assignment: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Rows (G, h) of the continuous problem with the binaries fixed to `assignment`."""
        mu = np.zeros(self.N * self.M)
        for n, i in enumerate(assignment):
            mu[n * self.M + i] = 1.0
        return self.G, self.h - self.Gmu @ mu
