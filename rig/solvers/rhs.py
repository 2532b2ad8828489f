"""The solvers' right-hand sides at one state, for tests and inspection (the kernels call the
compiled ones directly), and the choice of algorithm.

``rhs`` evaluates the equations of motion as the kernels do: the n = 2 scalar code, the dense
mass-matrix solve (O(n^3)) or the articulated-body recursion (O(n)); ``nonlinear_remainder`` the
exponential methods' remainder parts. ``rhs_algorithm`` picks the algorithm the rk4 and dop853
kernels run.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rig.errors import ConfigError
from rig.solvers.primitives import (ALG_DENSE, ALG_RECURSIVE, ALG_TWO, RECURSIVE_FROM_N, canon2,
                                    canon_n, rhs_alg, sincos_pair)
from rig.solvers.remainder import nsplit2, nsplit_n

if TYPE_CHECKING:
    from rig.chain import Chain


def bodies_array(chain: Chain) -> np.ndarray:
    """The (6, n) body table the recursive right-hand side reads (:meth:`rig.chain.Chain.
    body_table`: mass, length, com, inertia, damping, relative flag)."""
    return chain.body_table()


def rhs_algorithm(chain: Chain, algorithm: str = "auto") -> int:
    """The right-hand-side algorithm code for ``algorithm`` = ``"auto"`` (n = 2 scalar code; the
    dense solve below :data:`RECURSIVE_FROM_N` bodies, the O(n) recursion from there),
    ``"dense"`` or ``"recursive"``."""
    if algorithm == "auto":
        if chain.n == 2:
            return ALG_TWO
        return ALG_RECURSIVE if chain.n >= RECURSIVE_FROM_N else ALG_DENSE
    if algorithm == "dense":
        return ALG_DENSE
    if algorithm == "recursive":
        return ALG_RECURSIVE
    raise ConfigError(f"algorithm = {algorithm!r} is invalid: expected 'auto', 'dense' or "
                      "'recursive'")


def rhs(chain: Chain, y, ax: float = 0.0, ay: float = 0.0, *, canonical: bool = False,
        generic: bool = False, algorithm: str = "auto") -> np.ndarray:
    """The kernels' right-hand side at one state (for tests and inspection), shape (2n,).

    ``y = (theta, omega)`` gives ``(omega, th'')``; with ``canonical=True``, ``y = (theta, p)``
    gives ``(theta', p')``. ``generic=True`` forces the any-n code path for n = 2 (the dense solve
    unless ``algorithm="recursive"``); ``algorithm`` as in :func:`rhs_algorithm` (not for the
    canonical form, which is always dense).
    """
    y = np.ascontiguousarray(y, dtype=float)
    f = np.empty((1, y.size))
    n = chain.n
    w = np.empty((n, max(n + 2, 6)))
    args = (chain.H, chain.S, chain.C, chain.g_mps2, y, float(ax), float(ay), f, 0)
    if canonical:
        if n == 2 and not generic:
            canon2(*args)
        else:
            canon_n(*args, w)
        return f[0]
    alg = rhs_algorithm(chain, algorithm)
    if generic and alg == ALG_TWO:
        alg = ALG_DENSE
    rhs_alg(chain.H, chain.S, chain.C, chain.g_mps2, bodies_array(chain), alg, y, float(ax),
         float(ay), f, 0, w)
    return f[0]


def nonlinear_remainder(chain: Chain, y, *, generic: bool = False) -> np.ndarray:
    """The etd3 kernels' remainder parts at one state (for tests and inspection), shape (3, n).

    Rows N0, N1, N2 with ``th'' = (A z + B ax)_omega + N0 + ax N1 + ay N2`` for y = z = (theta,
    omega) (:class:`Etd3Coefficients`, section comment above). ``generic=True`` uses the any-n
    code for n = 2.
    """
    y = np.ascontiguousarray(y, dtype=float)
    n = chain.n
    from rig.solvers.etd3 import etd3_coefficients

    co = etd3_coefficients(chain, 1.0, "zoh")
    args = (chain.H, chain.S, chain.C, chain.g_mps2, co.p, co.q, co.bw)
    if n == 2 and not generic:
        s0, c0, s1, c1 = sincos_pair(y[0], y[1])
        return np.array(nsplit2(*args, y[0], y[1], y[2], y[3], s0, c0, s1, c1)).reshape(3, 2)
    out = np.empty((1, 3 * n))
    nsplit_n(*args, y[None, :], 0, out, 0, np.empty((n, n + 5)))
    return out.reshape(3, n)
