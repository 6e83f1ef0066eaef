"""The point-mass model of the SLIP planner: eqs. (1)-(2) of Bartlett & Manchester.

The CoM is a point mass; each sample interval [n t, (n + 1) t] holds the sum of the contact
accelerations a_n plus gravity constant (zero-order hold), so the positions are the double
integral s = P (sum a + g) t^2 + s_0 of (1). The paper's (1)-(2) start from rest: we add the
initial velocity v_0 (the term n t v_0), which a planner started mid-walk cannot leave out.
The paper's P has N rows for s_0 .. s_N; ours is the (N, N) map to s_1 .. s_N, whose first
row (1/2) is its first row and whose last row starts with (2N - 1)/2, as in (1).
"""

from __future__ import annotations

import numpy as np


def double_integration_matrix(n: int, dt: float) -> np.ndarray:
    """P of (1)-(2) with t^2 folded in: (n, n), P[m, j] = t^2 (2(m - j) + 1) / 2 for j <= m,
    so that s_{m+1} = s_0 + (m + 1) t v_0 + sum_j P[m, j] a_j."""
    m = np.arange(n)[:, None]
    j = np.arange(n)[None, :]
    return np.where(j <= m, 0.5 * dt * dt * (2.0 * (m - j) + 1.0), 0.0)


def velocity_matrix(n: int, dt: float) -> np.ndarray:
    """The single integral beside P: (n, n), v_{m+1} = v_0 + sum_{j <= m} t a_j."""
    return np.tril(np.full((n, n), dt))


def rollout(s0: np.ndarray, v0: np.ndarray, acc: np.ndarray, dt: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """(s, v), each (n + 1, 3) from s_0, v_0: eq. (2) with the initial velocity, for the
    total accelerations ``acc`` (n, 3) (contacts plus gravity) of the n intervals."""
    acc = np.asarray(acc, dtype=float).reshape(-1, 3)
    n = len(acc)
    steps = np.arange(1, n + 1)[:, None] * dt
    s = np.asarray(s0, float) + steps * np.asarray(v0, float) + double_integration_matrix(
        n, dt) @ acc
    v = np.asarray(v0, float) + velocity_matrix(n, dt) @ acc
    return np.vstack([s0, s]), np.vstack([v0, v])
