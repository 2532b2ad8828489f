"""etd3m: etd3 with each step spanning m whole held input samples (dt_s = m h_in), order 3.

The linearised chain exactly, the remainder's products with the held input against exact
per-sample weights, etd3's stage predictor, and a correction for the staircase's sawtooth in omega
(the model: the comment above :class:`Etd3mCoefficients`); measured order 3 to 4.5 in the step
(docs/solvers.md); m = 1 is etd3's map. Cost: 2 evaluations of N per step whatever m, plus a FIR
of ~6 n^2 products per sample. Needs a held base input (its steps are whole samples).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np

from rig.errors import ConfigError

from rig.jit import njit
from rig.linear import expm, monomial_integrals
from rig.solvers.primitives import NONFINITE, OK, chain_args, sincos4, sincos_pair, store
from rig.solvers.remainder import nsplit2, nsplit_n
from rig.solvers.base import HOLDS, PendulumSolver, Refinement, multisample_refinement
from rig.solvers.etd3 import ETD3_NODES, Etd3, etd3_hist2

if TYPE_CHECKING:
    from rig.chain import Chain


# ================================================================================================
# etd3m: etd3 with steps spanning m held input samples
# ================================================================================================
#
# etd3 treats the input as constant (or linear) within a step, so it steps at least once per
# sample. etd3m takes one step of H = m h_in over m whole samples: with the remainder split as in
# etd3 and the input gain written g(theta) = b + N1(theta) (b = H^-1 (-S), the linearised chain's),
#     z(H) = e^{AH} z(0) + int_0^H e^{A(H-s)} E [N0(z(s)) + u(s) g(theta(s)) + v(s) N2(theta(s))] ds
# exactly (u, v the held x and y inputs). The smooth parts N0, g, N2 are interpolated through the
# two Gauss nodes c_i H (as in etd3), and each product with the held input is integrated exactly
# against the staircase (or the straight lines): per input sample q and node i the weight
#     W_iq = int_0^H e^{A(H-s)} E l_i(s/H) phi_q(s) ds          (2n, n)
# (phi_q the hold's basis function of sample q: the indicator of interval q for zoh, the hat
# function for linear), the FIR of the lifted linear method generalised (sum_i W_iq b is its tap;
# for a linear chain the method is that exact map). The stages are predicted as in etd3: the exact
# linear step to c_i H plus K0(c_i H) N0^ and the staircase against b + N1^ (weights P_iq,
# int_0^{c_i H} e^{A(c_i H - s)} E phi_q(s) ds), N^ extrapolated linearly from the previous
# step's two stages to c_i H / 2. (Measured on the paper's 3000 s run, a quadratic predictor
# through one more past stage gains 5 to 20 % at m = 5 and 10 and loses 60 % at m = 20; on 100 s
# of it, iterating the stages to collocation, two more evaluations per step, gains 1.5 to 2.2
# times at m = 5 to 20.)
# Two remainder evaluations per step whatever m: the per-sample cost is the FIR, 8 n^2 products
# per sample and input (all four weight sets in one contiguous row per sample, the stage sets
# skipped past their nodes: on average 6 n^2).
#
# One correction is specific to m > 1 with zoh: omega(s) carries a sawtooth from the staircase,
# b (U(s) - U~(s)) with U = int u and U~ its smooth interpolant through the sample instants, zero
# there and, at a fraction f of interval q, b h du f (1 - f) / 2 (du = u_{q+1} - u_q). Its mean
# over an interval is b h du / 12, which is what the integral of N0's omega-dependence sees; the
# interpolation sees its values at the nodes instead, a bias of order |dN0/domega| |b| h du
# independent of H that would cap the accuracy (1e-7 relative on the paper's run at m = 2 to 10,
# measured). So each stage's omega, where N is evaluated (not propagated), is shifted by
#     (b + N1^) h du_i (1/12 - f_i (1 - f_i) / 2)
# (du_i from the samples next to the node's interval, within the step). At m = 1 the Gauss nodes
# have f (1 - f) / 2 = 1/12 exactly (no shift: etd3, where the input inside a step is constant);
# with the linear hold omega has no sawtooth at this order (no shift either). Measured on the
# paper's run the error then falls with H at order 3 to 4.5 (tests/rig/solvers/test_etd_multisample.py).
# Native state as etd3's (theta, omega, valid flag, step H, the remainder at the two stages).

ETD3M_BLOCKS = 4  # weight sets per sample: end node 0, end node 1, stage 1, stage 0


class Etd3mCoefficients(NamedTuple):
    """Everything :func:`etd3m_kernel` needs for one chain, input interval, m and hold, its second
    argument.

    Attributes
    ----------
    m : input samples per step; ``H = m h_in`` [s].
    phi : e^{AH}, (2n, 2n).
    phic : e^{A c_i H}, (2, 2n, 2n).
    wt : per-sample weights, (m + la, 4 (2n) n) with la = 1 for the linear hold: row q holds
        W_0q, W_1q (end of step, node 0, 1) and P_1q, P_0q (the stages; this order so that the
        rows past a stage's node are zero in a suffix), each (2n, n) row-major.
    wq : sum_q W_iq (the smooth part N0's quadrature weights), (2, 2n, n).
    pc : K0(c_i H) = sum_q P_iq, (2, 2n, n).
    xp : predictor weights (as etd3, in units of H), (2, 2).
    ck : the stage omega shift's factor h_in (1/12 - f_i (1 - f_i)/2) / (hi_i - lo_i), (2,)
        (zero for m = 1 or the linear hold).
    lohi : (2, 2) the samples (within the step) whose difference is du_i.
    widths : (e0, e1, w4, w3, w2): rows [0, e0) of wt are used in full (w4 numbers), rows
        [e0, e1) in their first w3 (P_0q is zero there), the rest in their first w2.
    p, q, bw : as :class:`Etd3Coefficients`.
    """

    m: int
    phi: np.ndarray
    phic: np.ndarray
    wt: np.ndarray
    wq: np.ndarray
    pc: np.ndarray
    xp: np.ndarray
    ck: np.ndarray
    lohi: np.ndarray
    widths: np.ndarray
    p: np.ndarray
    q: np.ndarray
    bw: np.ndarray


def piece_integral(a: np.ndarray, n: int, t_end: float, s_a: float, s_b: float, poly):
    """int_{s_a}^{s_b} e^{A(t_end - s)} E p(s) ds for a polynomial p (numpy Polynomial in s),
    (2n, n): e^{A(t_end - s_b)} sum_k p~_k K_k(s_b - s_a), p~ p in x = (s - s_a)/(s_b - s_a).
    The weights of the held input's polynomial pieces, here and in :mod:`rig.solvers.etd4m`."""
    length = s_b - s_a
    coef = poly(np.polynomial.Polynomial([s_a, length])).coef
    _, ks = monomial_integrals(a, np.arange(n, 2 * n), length, max(coef.size - 1, 0) + 1)
    acc = sum(cf * ks[k] for k, cf in enumerate(coef))
    return expm(a * (t_end - s_b)) @ acc


def check_hold_and_m(hold: str, m) -> None:
    """ConfigError unless ``hold`` is one of HOLDS and ``m`` (samples per step) is >= 1."""
    if hold not in HOLDS:
        raise ConfigError(f"hold = {hold!r} is invalid: expected one of {', '.join(HOLDS)}")
    if m < 1:
        raise ConfigError(f"m = {m!r} is invalid: expected a whole number of samples >= 1")


def staircase_weights(a: np.ndarray, n: int, h_in: float, m: int, la: int, nodes, lag
                      ) -> np.ndarray:
    """The per-sample weights of a step of ``m`` held samples (``la`` = 1 for the linear hold),
    (m + la, 2 k, 2n, n) for k = len(nodes): set i < k the integral over the step of
    e^{A(H - s)} E lag[i](s) times the sample's basis function, set 2k - 1 - i the integral up to
    node i (c_i H) of e^{A(c_i H - s)} E times it."""
    poly = np.polynomial.Polynomial
    k = len(nodes)
    big_h = m * h_in
    wt = np.zeros((m + la, 2 * k, 2 * n, n))
    for qq in range(m):
        s_a, s_b = qq * h_in, (qq + 1) * h_in
        # the hold's basis functions on interval qq: (tap, polynomial in s)
        if la:
            pieces = [(qq, poly([1.0 + qq, -1.0 / h_in])), (qq + 1, poly([-qq, 1.0 / h_in]))]
        else:
            pieces = [(qq, poly([1.0]))]
        for tap, bas in pieces:
            for i in range(k):
                wt[tap, i] += piece_integral(a, n, big_h, s_a, s_b, lag[i] * bas)
                ci = nodes[i] * big_h
                if s_a < ci:
                    wt[tap, 2 * k - 1 - i] += piece_integral(a, n, ci, s_a, min(s_b, ci), bas)
    return wt


def sawtooth_corrections(nodes, m: int, la: int, h_in: float) -> tuple[np.ndarray, np.ndarray]:
    """The zero-order hold's sawtooth correction at each node (``ck`` [s], and the samples
    ``lohi`` its difference spans); zeros for m = 1 or the linear hold."""
    ck = np.zeros(len(nodes))
    lohi = np.zeros((len(nodes), 2), dtype=np.int64)
    if m > 1 and not la:
        for i, ci in enumerate(nodes):
            x = ci * m
            qq = min(int(math.floor(x)), m - 1)
            f = x - qq
            lo, hi = max(qq - 1, 0), min(qq + 1, m - 1)
            ck[i] = h_in * (1.0 / 12.0 - 0.5 * f * (1.0 - f)) / (hi - lo)
            lohi[i] = lo, hi
    return ck, lohi


def linear_parts(chain: "Chain", b: np.ndarray) -> dict:
    """``p = H^-1 K``, ``q = H^-1 C`` and the input gain ``bw`` (rows n: of ``b``)."""
    hinv = np.linalg.inv(chain.H)
    arr = np.ascontiguousarray
    return dict(p=arr(hinv @ chain.K), q=arr(hinv @ chain.C), bw=arr(b[chain.n:, 0]))


@functools.lru_cache(maxsize=32)
def etd3m_coefficients(chain: Chain, h_in: float, m: int, hold: str) -> Etd3mCoefficients:
    """The matrices of :func:`etd3m_kernel` for ``chain``, input interval ``h_in`` [s], ``m``
    samples per step and ``hold`` (cached; ~3 m small matrix exponentials)."""
    check_hold_and_m(hold, m)
    a, b = chain.state_space()
    n = chain.n
    n2 = 2 * n
    c = ETD3_NODES
    big_h = m * h_in
    la = int(hold == "linear")
    poly = np.polynomial.Polynomial
    lag = [poly([-c[1], 1.0 / big_h]) / (c[0] - c[1]), poly([-c[0], 1.0 / big_h]) / (c[1] - c[0])]
    wt = staircase_weights(a, n, h_in, m, la, c, lag)
    phic = np.array([expm(a * (ci * big_h)) for ci in c])
    nodes = (c[0] - 1.0, c[1] - 1.0)
    xp = np.array([[(0.5 * ci - nodes[1]) / (nodes[0] - nodes[1]),
                    (0.5 * ci - nodes[0]) / (nodes[1] - nodes[0])] for ci in c])
    ck, lohi = sawtooth_corrections(c, m, la, h_in)
    # samples [0, e0) carry all four weight sets, [e0, e1) three (stage 0's ended), the rest two
    e0, e1 = (min(int(math.ceil(ci * m * (1.0 + 1e-12) - 1e-12)) + la, m + la) for ci in c)
    widths = np.array([e0, e1, 4 * n2 * n, 3 * n2 * n, 2 * n2 * n], dtype=np.int64)
    arr = np.ascontiguousarray
    return Etd3mCoefficients(
        m=m, phi=arr(expm(a * big_h)), phic=arr(phic),
        wt=arr(wt.reshape(m + la, ETD3M_BLOCKS * n2 * n)), wq=arr(wt[:, :2].sum(axis=0)),
        pc=arr(wt[:, :1:-1].sum(axis=0)), xp=arr(xp), ck=ck, lohi=lohi, widths=widths,
        **linear_parts(chain, b))


def check_samples_per_step(solver, held) -> int:
    """A multi-sample method's m for this block, or ConfigError naming what is valid."""
    m, out_every, n_intervals, h_in = (solver.samples_per_step, held.out_every,
                                       held.n_intervals, held.h_in)
    if out_every % m or n_intervals % m:
        ok = [k for k in range(1, out_every + 1) if out_every % k == 0 and n_intervals % k == 0]
        raise ConfigError(
            f"samples_per_step = {m} (dt_s = {m * h_in:.6g} s) is invalid: an {solver.name} step "
            f"must divide the output interval ({out_every} input intervals) and the run "
            f"({n_intervals} intervals); valid: {', '.join(map(str, ok))} input intervals "
            f"(dt_s = {', '.join(f'{k * h_in:.6g}' for k in ok)} s)")
    return m


class MultiSample(PendulumSolver):
    """Shared behaviour of the methods whose steps span whole held input samples."""

    kind: ClassVar[str] = "exponential"
    multisample: ClassVar[bool] = True

    def __post_init__(self):
        m = self.samples_per_step
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
            raise ConfigError(f"samples_per_step = {m!r} is invalid: expected a whole number >= 1 "
                              f"of input intervals per {self.name} step")

    def on_grid(self, substeps: int, samples_per_step: int):
        if substeps != 1:
            raise ConfigError(f"substeps = {substeps!r} is invalid for {self.name}: its steps "
                              "span whole input intervals (set samples_per_step), substeps must "
                              "be 1")
        return dataclasses.replace(self, samples_per_step=int(samples_per_step))


@dataclass(frozen=True)
class Etd3m(MultiSample):
    """etd3m with ``samples_per_step`` input intervals per step (m >= 1, dividing the output
    interval and the block)."""

    samples_per_step: int = 1

    name: ClassVar[str] = "etd3m"
    order: ClassVar[int] = 3
    description: ClassVar[str] = (
        "etd3 with each step spanning m whole held input samples (dt_s = m input intervals): the "
        "linearised chain exactly, the remainder's products with the held input against "
        "per-sample weights (2 evaluations per step)")
    native: ClassVar[str] = "theta,omega,history"
    history_rows: ClassVar[int] = 2

    def refined(self) -> Refinement:
        def half_sample():
            return Refinement(Etd3(substeps=2), 2**3 / (2**3 - 1.0), (
                "Richardson: |y - y_ref| * 2^3/(2^3 - 1) against etd3 at dt_s / 2 (half an input "
                "interval; etd3m at m = 1 is etd3's map) (order p = 3); valid while the error is "
                "in its asymptotic range"))
        return multisample_refinement(self, self.samples_per_step, half_sample)

    def advance(self, chain, native, held, *, h0_s=float("nan")):
        y = native
        y_out = self.out_rows(chain, y, held)
        ax, ay, sa, _ = held.kernel_args
        m = check_samples_per_step(self, held)
        co = etd3m_coefficients(chain, float(held.h_in), m, held.hold)
        big_h = m * held.h_in
        z, hist, have = self.split_history(chain, y, big_h)
        kernel = etd3m_kernel2 if chain.n == 2 else etd3m_kernel
        status, nrow, i_done, nfev = kernel(
            chain_args(chain), co, ax, ay, sa, m, held.n_intervals // m, held.out_every // m, z,
            y_out, hist, have)
        y = np.concatenate([z, [1.0, big_h], hist.reshape(-1)])
        return self.finish(chain, status, y, y_out, nrow, i_done, held, n_steps=i_done // m,
                           n_fev=nfev)


# ================================================================================================
# compiled kernels
# ================================================================================================

@njit(cache=True, inline="always")
def _etd3m_fir(u, i0, stride, wt, widths, acc):
    """acc = sum_q u[(i0 + q) stride] wt[q], skipping the rows' zero suffixes (``widths``)."""
    for r in range(widths[2]):
        acc[r] = 0.0
    lo = 0
    for seg in range(3):
        hi = widths[seg] if seg < 2 else wt.shape[0]
        width = widths[2 + seg]
        for qq in range(lo, hi):
            x = u[(i0 + qq) * stride]
            for r in range(width):
                acc[r] += x * wt[qq, r]
        lo = hi


@njit(cache=True)
def _etd3m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w):
    """hn[i] = (N0, N1, N2) at the state zs[i] (the n = 2 scalar code where n = 2)."""
    if zs.shape[1] == 4:
        s0, c0, s1, c1 = sincos_pair(zs[i, 0], zs[i, 1])
        (hn[i, 0], hn[i, 1], hn[i, 2], hn[i, 3], hn[i, 4],
         hn[i, 5]) = nsplit2(hc, s, cm, g, p, q, bw, zs[i, 0], zs[i, 1], zs[i, 2], zs[i, 3], s0,
                              c0, s1, c1)
    else:
        nsplit_n(hc, s, cm, g, p, q, bw, zs, i, hn, i, w)


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3m_kernel(chain, co, ax, ay, sa, m, n_steps, out_steps, y, y_out, hist, have):
    """etd3m (see the section comment above): ``n_steps`` steps of ``m`` input samples, any n.

    ``chain``: :class:`rig.solvers.primitives.ChainArgs`; ``co``: :class:`Etd3mCoefficients`
    (``co.wt`` the per-sample weights). ``ax``, ``ay`` hold the samples (``ay`` read with stride
    ``sa``: 0 for none); a row is stored every ``out_steps`` steps
    and at the end. ``hist`` (2, 3n) and ``have`` as :func:`etd3_kernel`. ``y`` (2n,) is
    overwritten with the end state. Returns (status, rows written, input intervals done,
    remainder evaluations)."""
    hc, s, cm, g = chain
    p, q, bw, phi, phic, wt = co.p, co.q, co.bw, co.phi, co.phic, co.wt
    wq, pc, xp, ck, lohi, widths = co.wq, co.pc, co.xp, co.ck, co.lohi, co.widths
    n2 = y.shape[0]
    n = n2 // 2
    nw = n2 * n
    kw = wt.shape[1]
    acc = np.empty(kw)
    accv = np.zeros(kw)
    zs = np.empty((2, n2))
    hn = np.empty((2, 3 * n))
    gg = np.empty((2, n))
    nh = np.empty((2, 3 * n))
    zt = np.empty(n2)
    w = np.empty((n, n + 5))
    nev = 0
    zero = n_steps - n_steps  # see _NOTE_LITERALS (rig.solvers.primitives)
    one = zero + 1
    if not have:
        for c in range(n2):
            zs[zero, c] = y[c]
        _etd3m_eval(hc, s, cm, g, p, q, bw, zs, zero, hist, w)
        for c in range(3 * n):
            hist[one, c] = hist[zero, c]
        nev += 1
    store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        # the FIR: acc = sum_q u_q wt[q] (all four weight sets), accv the same for ay
        _etd3m_fir(ax, i0, 1, wt, widths, acc)
        if sa:
            _etd3m_fir(ay, i0, sa, wt, widths, accv)
        # predicted stages
        for i in range(2):
            x0 = xp[i, 0]
            x1 = xp[i, 1]
            for c in range(3 * n):
                nh[i, c] = x0 * hist[0, c] + x1 * hist[1, c]
            for j in range(n):
                gg[i, j] = bw[j] + nh[i, n + j]
            du = ck[i] * (ax[i0 + lohi[i, 1]] - ax[i0 + lohi[i, 0]])
            dv = ck[i] * (ay[(i0 + lohi[i, 1]) * sa] - ay[(i0 + lohi[i, 0]) * sa])
            base = (3 - i) * nw
            for r in range(n2):
                t = 0.0
                for c in range(n2):
                    t += phic[i, r, c] * y[c]
                for j in range(n):
                    t += (acc[base + r * n + j] * gg[i, j]
                          + accv[base + r * n + j] * nh[i, 2 * n + j]
                          + pc[i, r, j] * nh[i, j])
                zs[i, r] = t
            for j in range(n):
                zs[i, n + j] += du * gg[i, j] + dv * nh[i, 2 * n + j]
        for i in range(2):
            _etd3m_eval(hc, s, cm, g, p, q, bw, zs, i, hn, w)
        nev += 2
        # the step
        for r in range(n2):
            t = 0.0
            for c in range(n2):
                t += phi[r, c] * y[c]
            for i in range(2):
                base = i * nw
                for j in range(n):
                    t += (acc[base + r * n + j] * (bw[j] + hn[i, n + j])
                          + accv[base + r * n + j] * hn[i, 2 * n + j] + wq[i, r, j] * hn[i, j])
            zt[r] = t
        for r in range(n2):
            y[r] = zt[r]
        for i in range(2):
            for c in range(3 * n):
                hist[i, c] = hn[i, c]
        left -= 1
        if left == 0 or k + 1 == n_steps:
            left = out_steps
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                return NONFINITE, row, (k + 1) * m, nev
    return OK, row, n_steps * m, nev


@njit(cache=True, inline="always")
def _etd3m_w2(r, acc, accv, base, pc, ip, e0, e1, g0, g1, v0, v1):
    """Row r of pc[ip] @ e + the (4, 2) blocks at ``base`` of acc @ g and accv @ v (n = 2)."""
    k = base + 2 * r
    return (((acc[k] * g0 + acc[k + 1] * g1) + (pc[ip, r, 0] * e0 + pc[ip, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, inline="always")
def _etd3m_row2(mat, i, r, z, acc, accv, base, pc, ip, e0, e1, g0, g1, v0, v1):
    """Row r of mat[i] @ z + pc[ip] @ e + the (4, 2) blocks at ``base`` of acc @ g and accv @ v
    (n = 2; ``z`` the state's four numbers)."""
    z0, z1, z2, z3 = z
    k = base + 2 * r
    return (((mat[i, r, 0] * z0 + mat[i, r, 1] * z1) + (mat[i, r, 2] * z2 + mat[i, r, 3] * z3))
            + ((acc[k] * g0 + acc[k + 1] * g1) + (pc[ip, r, 0] * e0 + pc[ip, r, 1] * e1))
            + (accv[k] * v0 + accv[k + 1] * v1))


@njit(cache=True, nogil=True, fastmath={"contract"})
def etd3m_kernel2(chain, co, ax, ay, sa, m, n_steps, out_steps, y, y_out, hist, have):
    """:func:`etd3m_kernel` for the n = 2 chain: the state, the stages and the remainder parts in
    scalars, the four stage angles' sin and cos in one branch (:func:`sincos4`)."""
    hc, s, cm, g = chain
    p, q, bw, phi, phic, wt = co.p, co.q, co.bw, co.phi, co.phic, co.wt
    wq, pc, xp, ck, lohi, widths = co.wq, co.pc, co.xp, co.ck, co.lohi, co.widths
    kw = wt.shape[1]
    acc = np.empty(kw)
    accv = np.zeros(kw)
    phi3 = phi.reshape((1, 4, 4))
    nev = 0
    z0, z1, z2, z3 = y[0], y[1], y[2], y[3]
    if not have:
        s0, c0, s1, c1 = sincos_pair(z0, z1)
        a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, z0, z1, z2, z3, s0, c0,
                                                s1, c1)
        b00, b01, b10, b11, b20, b21 = a00, a01, a10, a11, a20, a21
        nev += 1
    else:
        a00, a01, a10, a11, a20, a21 = (hist[0, 0], hist[0, 1], hist[0, 2], hist[0, 3],
                                        hist[0, 4], hist[0, 5])
        b00, b01, b10, b11, b20, b21 = (hist[1, 0], hist[1, 1], hist[1, 2], hist[1, 3],
                                        hist[1, 4], hist[1, 5])
    bw0 = bw[0]
    bw1 = bw[1]
    zero = n_steps - n_steps  # see _NOTE_LITERALS (rig.solvers.primitives)
    one = zero + 1
    store(y, y_out, zero)
    row = one
    left = out_steps
    for k in range(n_steps):
        i0 = k * m
        _etd3m_fir(ax, i0, 1, wt, widths, acc)
        if sa:
            _etd3m_fir(ay, i0, sa, wt, widths, accv)
        # stage 0: predicted parts, then the exact step to c0 H with the staircase against b + N1^
        x0 = xp[0, 0]
        x1 = xp[0, 1]
        e0 = x0 * a00 + x1 * b00
        e1 = x0 * a01 + x1 * b01
        g0 = bw0 + (x0 * a10 + x1 * b10)
        g1 = bw1 + (x0 * a11 + x1 * b11)
        v0 = x0 * a20 + x1 * b20
        v1 = x0 * a21 + x1 * b21
        du = ck[0] * (ax[i0 + lohi[0, 1]] - ax[i0 + lohi[0, 0]])
        dv = ck[0] * (ay[(i0 + lohi[0, 1]) * sa] - ay[(i0 + lohi[0, 0]) * sa])
        p0 = _etd3m_row2(phic, 0, 0, (z0, z1, z2, z3), acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p1 = _etd3m_row2(phic, 0, 1, (z0, z1, z2, z3), acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p2 = _etd3m_row2(phic, 0, 2, (z0, z1, z2, z3), acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p3 = _etd3m_row2(phic, 0, 3, (z0, z1, z2, z3), acc, accv, 24, pc, 0, e0,
                         e1, g0, g1, v0, v1)
        p2 += du * g0 + dv * v0
        p3 += du * g1 + dv * v1
        # stage 1
        x0 = xp[1, 0]
        x1 = xp[1, 1]
        e0 = x0 * a00 + x1 * b00
        e1 = x0 * a01 + x1 * b01
        g0 = bw0 + (x0 * a10 + x1 * b10)
        g1 = bw1 + (x0 * a11 + x1 * b11)
        v0 = x0 * a20 + x1 * b20
        v1 = x0 * a21 + x1 * b21
        du = ck[1] * (ax[i0 + lohi[1, 1]] - ax[i0 + lohi[1, 0]])
        dv = ck[1] * (ay[(i0 + lohi[1, 1]) * sa] - ay[(i0 + lohi[1, 0]) * sa])
        q0 = _etd3m_row2(phic, 1, 0, (z0, z1, z2, z3), acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q1 = _etd3m_row2(phic, 1, 1, (z0, z1, z2, z3), acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q2 = _etd3m_row2(phic, 1, 2, (z0, z1, z2, z3), acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q3 = _etd3m_row2(phic, 1, 3, (z0, z1, z2, z3), acc, accv, 16, pc, 1, e0,
                         e1, g0, g1, v0, v1)
        q2 += du * g0 + dv * v0
        q3 += du * g1 + dv * v1
        sp0, cp0, sp1, cp1, sq0, cq0, sq1, cq1 = sincos4(p0, p1, q0, q1)
        a00, a01, a10, a11, a20, a21 = nsplit2(hc, s, cm, g, p, q, bw, p0, p1, p2, p3, sp0,
                                                cp0, sp1, cp1)
        b00, b01, b10, b11, b20, b21 = nsplit2(hc, s, cm, g, p, q, bw, q0, q1, q2, q3, sq0,
                                                cq0, sq1, cq1)
        nev += 2
        # the step: e^{AH} z + node 0's and node 1's weights
        n0 = (_etd3m_row2(phi3, 0, 0, (z0, z1, z2, z3), acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(0, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n1 = (_etd3m_row2(phi3, 0, 1, (z0, z1, z2, z3), acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(1, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n2 = (_etd3m_row2(phi3, 0, 2, (z0, z1, z2, z3), acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(2, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        n3 = (_etd3m_row2(phi3, 0, 3, (z0, z1, z2, z3), acc, accv, 0, wq, 0, a00, a01, bw0 + a10,
                          bw1 + a11, a20, a21)
              + _etd3m_w2(3, acc, accv, 8, wq, 1, b00, b01, bw0 + b10, bw1 + b11, b20,
                          b21))
        z0 = n0
        z1 = n1
        z2 = n2
        z3 = n3
        left -= 1
        if left == 0 or k + 1 == n_steps:
            left = out_steps
            y[0] = z0
            y[1] = z1
            y[2] = z2
            y[3] = z3
            ok = store(y, y_out, row)
            row += 1
            if not ok:
                etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
                return NONFINITE, row, (k + 1) * m, nev
    y[0] = z0
    y[1] = z1
    y[2] = z2
    y[3] = z3
    etd3_hist2(hist, a00, a01, a10, a11, a20, a21, b00, b01, b10, b11, b20, b21)
    return OK, row, n_steps * m, nev
