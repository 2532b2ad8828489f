"""etd4m: the multi-sample exponential integrator with three Gauss nodes and a quadratic
remainder over the stages.

Like etd3m (:mod:`rig.solvers.etd3m`), one step spans ``H = m h_in``, m whole held input samples:
the linearised chain and the held input are propagated exactly, and only the nonlinear remainder
(N0, the input gain's nonlinear part N1 and the vertical gain N2, :func:`rig.solvers.rhs.
nonlinear_remainder`) is approximated,

    z(H) = e^{AH} z(0) + int_0^H e^{A(H-s)} E [N0(z) + u(s) (b + N1(theta)) + v(s) N2(theta)] ds.

The differences from etd3m, both raising the order in the step:

* **three Gauss-Legendre nodes** c_i = 1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10: N0, b + N1 and
  N2 are interpolated by the quadratic through the three stages, and each product with the held
  input is integrated exactly against the staircase (or the straight lines of the linear hold):
  per sample q and node i the weight ``W_iq = int_0^H e^{A(H-s)} E l_i(s/H) phi_q(s) ds``, with
  the hold's basis function phi_q (as etd3m, so the input's kinks at every sample are integrated,
  never assumed smooth);
* **the stages predicted by a quadratic**: the remainder over ``[0, c_i H]`` is the quadratic
  through the previous step's three stages (at c_j - 1 in units of H), integrated exactly against
  e^{A(c_i H - s)} for N0 (matrices ``PN[i, j]``, no per-sample cost), and, for the products with
  the input, held at its value at c_i H / 2 against the staircase (one weight set per stage: the
  input gain's nonlinear part N1 is of the order of theta^2 relative to b, so its variation over
  a stage enters at that relative size times H^2).

The stage omegas, where N is evaluated, carry etd3m's correction for the staircase's sawtooth
(the interpolation then sees each interval's mean). Three remainder evaluations per step; per
sample a FIR of 6 weight sets (2n x n each), the stage sets skipped past their nodes (for n = 2
every row in full, which the compiler vectorises; without a vertical input the n = 2 kernel
forms neither N2 nor its products with the zero input, the same numbers, and forms the FIR, which
no state enters, as BLAS products of :data:`FIR_CHUNK_STEPS` steps' input windows ahead of its
serial chain: the same sums within round-off; docs/benchmarks/history.md, speed round 7). The first
step after a (re)start predicts with N(z0) at one more evaluation; the three stages are part of
the native state (theta, omega, valid flag, step H, then 9n numbers), so blocks that end on output
rows continue bit for bit.

Error: order 4 in H (the stages' error O(H^4) through the quadratic prediction; the quadrature
through three nodes is of order 6 for a smooth remainder); measured on the paper's run in
``tests/rig/solvers/test_etd4m.py`` and BENCHMARKS.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np


from rig.solvers._kernels import etd4m_kernel, etd4m_kernel2, etd4m_kernel2h
from rig.solvers.base import Refinement, multisample_refinement
from rig.solvers.dop853 import Dop853
from rig.solvers.etd3m import (MultiSample, _piece_integral, check_hold_and_m,
                               check_samples_per_step, linear_parts, sawtooth_corrections,
                               staircase_weights)

if TYPE_CHECKING:
    from rig.chain import Chain


def _expm(a):
    """scipy.linalg.expm, imported on first use (importing rig.solvers stays light)."""
    import scipy.linalg

    return scipy.linalg.expm(a)


_R15 = math.sqrt(15.0)
ETD4M_NODES = (0.5 - _R15 / 10.0, 0.5, 0.5 + _R15 / 10.0)
ETD4M_SETS = 6  # weight sets per sample: end nodes 0, 1, 2, then stages 2, 1, 0
#: n = 2 without a vertical input: the kernel that forms neither N2 nor its zero products
#: (rig.solvers._kernels.etd4m_kernel2h, the same numbers as etd4m_kernel2); False runs
#: etd4m_kernel2 there (the path before, for benchmarks/targets.py)
HORIZONTAL_KERNEL = True
#: steps whose input FIR etd4m_kernel2h forms as one BLAS product before its serial chain reads
#: it (the same sums within round-off; 0: the FIR in the loop, step by step, the path before,
#: for benchmarks/targets.py), at most what keeps the product in one BLAS thread
#: (:func:`fir_chunk_steps`)
FIR_CHUNK_STEPS = 256
#: OpenBLAS computes a product of m n k <= 65536 x GEMM_MULTITHREAD_THRESHOLD (4 by default)
#: multiply-adds in the calling thread (interface/gemm.c); above, it wakes its threads, whose
#: start and spinning cost more CPU than such a product
BLAS_ONE_THREAD_MULADDS = 65536 * 4


def fir_chunk_steps(window: int) -> int:
    """Steps per BLAS product of etd4m_kernel2h's input FIR for ``window`` samples a step
    (``m`` + 1 for the linear hold): :data:`FIR_CHUNK_STEPS`, fewer where the product of
    (steps, window) by (window, 48) would exceed :data:`BLAS_ONE_THREAD_MULADDS`; 0 if
    :data:`FIR_CHUNK_STEPS` is 0."""
    if FIR_CHUNK_STEPS <= 0:
        return 0
    return max(1, min(FIR_CHUNK_STEPS, BLAS_ONE_THREAD_MULADDS // (48 * window)))


@dataclass(frozen=True, eq=False)
class Etd4mCoefficients:
    """Everything :func:`etd4m_kernel` needs for one chain, input interval, m and hold.

    Attributes
    ----------
    m : input samples per step; ``H = m h_in`` [s].
    phi : e^{AH}, (2n, 2n).
    phic : e^{A c_i H}, (3, 2n, 2n).
    wt : per-sample weights, (m + la, 6 (2n) n), la = 1 for the linear hold: row q holds W_0q,
        W_1q, W_2q (end of step) and P_2q, P_1q, P_0q (the stages, ``int_0^{c_i H}
        e^{A(c_i H - s)} E phi_q(s) ds``), each (2n, n) row-major.
    wq : sum_q W_iq (N0's end quadrature weights), (3, 2n, n).
    pn : PN[i, j] = int_0^{c_i H} e^{A(c_i H - s)} E L_j(s/H) ds, L_j the Lagrange basis through
        the previous step's nodes c_j - 1, (3, 3, 2n, n).
    xp : L_j(c_i / 2), the predictor of the input gain at the stage's midpoint, (3, 3).
    ck : the stage omega shift's factor h_in (1/12 - f_i (1 - f_i)/2) / (hi_i - lo_i), (3,)
        (zero for m = 1 or the linear hold).
    lohi : (3, 2) the samples (within the step) whose difference is du_i.
    widths : (e0, e1, e2): rows [0, e0) of wt carry 6 sets, [e0, e1) 5, [e1, e2) 4, the rest 3.
    p, q, bw : as :class:`rig.solvers.etd3.Etd3Coefficients`.
    """

    m: int
    phi: np.ndarray
    phic: np.ndarray
    wt: np.ndarray
    wq: np.ndarray
    pn: np.ndarray
    xp: np.ndarray
    ck: np.ndarray
    lohi: np.ndarray
    widths: np.ndarray
    p: np.ndarray
    q: np.ndarray
    bw: np.ndarray


def _lagrange(nodes, j, scale):
    """The Lagrange basis polynomial j through ``nodes`` (in units of ``scale``), in s."""
    poly = np.polynomial.Polynomial([1.0])
    for k, ck in enumerate(nodes):
        if k != j:
            poly = poly * np.polynomial.Polynomial([-ck, 1.0 / scale]) / (nodes[j] - ck)
    return poly


@functools.lru_cache(maxsize=32)
def etd4m_coefficients(chain: Chain, h_in: float, m: int, hold: str) -> Etd4mCoefficients:
    """The matrices of :func:`etd4m_kernel` for ``chain``, input interval ``h_in`` [s], ``m``
    samples per step and ``hold`` (cached; ~6 m small matrix exponentials)."""
    check_hold_and_m(hold, m)
    a, b = chain.state_space()
    n = chain.n
    n2 = 2 * n
    c = ETD4M_NODES
    big_h = m * h_in
    la = int(hold == "linear")
    lag = [_lagrange(c, i, big_h) for i in range(3)]
    wt = staircase_weights(a, n, h_in, m, la, c, lag)
    prev = tuple(ci - 1.0 for ci in c)
    lprev = [_lagrange(prev, j, big_h) for j in range(3)]
    pn = np.array([[_piece_integral(a, n, ci * big_h, 0.0, ci * big_h, lprev[j])
                    for j in range(3)] for ci in c])
    xp = np.array([[lprev[j](0.5 * ci * big_h) for j in range(3)] for ci in c])
    phic = np.array([_expm(a * (ci * big_h)) for ci in c])
    ck, lohi = sawtooth_corrections(c, m, la, h_in)
    widths = np.array([min(int(math.ceil(ci * m * (1.0 + 1e-12) - 1e-12)) + la, m + la)
                       for ci in c], dtype=np.int64)
    arr = np.ascontiguousarray
    return Etd4mCoefficients(
        m=m, phi=arr(_expm(a * big_h)), phic=arr(phic),
        wt=arr(wt.reshape(m + la, ETD4M_SETS * n2 * n)), wq=arr(wt[:, :3].sum(axis=0)),
        pn=arr(pn), xp=arr(xp), ck=ck, lohi=lohi, widths=widths, **linear_parts(chain, b))


@dataclass(frozen=True)
class Etd4m(MultiSample):
    """etd4m with ``samples_per_step`` input intervals per step (as :class:`rig.solvers.etd3m.
    Etd3m`)."""

    samples_per_step: int = 1

    name: ClassVar[str] = "etd4m"
    order: ClassVar[int] = 4
    description: ClassVar[str] = (
        "etd3m with three Gauss nodes and the stages predicted by the quadratic through the "
        "previous step's three (rig.solvers.etd4m; 3 evaluations per step)")
    native: ClassVar[str] = "theta,omega,history3"
    history_rows: ClassVar[int] = 3

    def refined(self) -> Refinement:
        def reference():
            return Refinement(Dop853(rtol=1e-12, atol=1e-14), 1.0, (
                "|y - y_ref| against dop853 at rtol = 1e-12, atol = 1e-14 from the same start "
                f"state ({self.name} at one input interval per step cannot halve its step)"))
        return multisample_refinement(self, self.samples_per_step, reference)

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, ay, sa, _ = held.kernel_args
        m = check_samples_per_step(self, held)
        co = etd4m_coefficients(chain, float(held.h_in), m, held.hold)
        big_h = m * held.h_in
        z, hist, have = self.split_history(chain, y, big_h)
        if chain.n == 2 and not sa and HORIZONTAL_KERNEL:
            status, nrow, i_done, nfev = etd4m_kernel2h(
                chain.H, chain.S, chain.C, chain.g_mps2, co.p, co.q, co.bw, co.phi, co.phic,
                co.wt, co.wq, co.pn, co.xp, co.ck, co.lohi, ax, m, held.n_intervals // m,
                held.out_every // m, z, y_out, hist, have, fir_chunk_steps(co.wt.shape[0]))
        else:
            status, nrow, i_done, nfev = (etd4m_kernel2 if chain.n == 2 else etd4m_kernel)(
                chain.H, chain.S, chain.C, chain.g_mps2, co.p, co.q, co.bw, co.phi, co.phic,
                co.wt, co.wq, co.pn, co.xp, co.ck, co.lohi, co.widths, ax, ay, sa, m,
                held.n_intervals // m, held.out_every // m, z, y_out, hist, have)
        y = np.concatenate([z, [1.0, big_h], hist.reshape(-1)])
        return self.finish(chain, status, y, y_out, nrow, i_done, held, n_steps=i_done // m,
                           n_fev=nfev)
