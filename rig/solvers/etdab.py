"""etdab: exponential Adams-Bashforth for the coupled bench, order 4 (the acquisition's default).

The linear bench exactly (``Phi``, ``Gamma`` at ``h = 1 / (fs substeps)``), the nonlinear remainder
``f`` by the polynomial through its values at the last four nodes integrated against ``e^{A s}``
(weights :func:`etd_ab_phase_weights`). The nodes are every ``every`` steps: at
every step (``every`` = 1), or, by default where the nonlinearity is weak and the drive's band
allows, every 5 (:func:`rig.bench.model.remainder_every`: the remainder carries the drive's band,
so four nodes 5 ms apart resolve it), the polynomial extrapolated over the steps between. The
native state is those four remainder values (``(4, rows)``; with ``every`` > 1 one more row: the
steps since the newest node), so blocks continue bit for bit; the first steps after a start
build it up. Kernel: :func:`etd_ab_kernel` (equations: :mod:`rig.solvers.coupled`), run
unrolled for the matrices' exact-zero pattern (:func:`etdab_kernel`: the same values).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from rig.jit import njit
from rig.linear import monomial_integrals
from rig.errors import ConfigError
from rig.solvers.base import whole_number
from rig.solvers.bench_base import BenchSolver
from rig.solvers.coupled import arg_groups, kernel_scratch, remainder2_fast, remainder_n
from rig.unrolled import load

ETDAB_ORDER = 4  # past remainder values per step (the order of the method)


class EtdabMatrices(NamedTuple):
    """The matrices of :func:`etd_ab_kernel` for one bench and step, its second argument.

    phi_t, gam : the linear bench's step Phi (transposed) and Gamma over h (zero-order hold).
    w, lagv : :func:`etd_ab_phase_weights`; w_rows, a_cols : :func:`etd_ab_sparsity`."""

    phi_t: np.ndarray
    gam: np.ndarray
    w: np.ndarray
    lagv: np.ndarray
    w_rows: int
    a_cols: int


@dataclass(frozen=True)
class Etdab(BenchSolver):
    """Exponential Adams-Bashforth 4 with ``substeps`` steps per DAC interval and the remainder
    evaluated at every ``every``-th step (1: every step)."""

    substeps: int = 1
    every: int = 1

    name: ClassVar[str] = "etdab"
    order: ClassVar[int] = ETDAB_ORDER
    description: ClassVar[str] = ("exponential Adams-Bashforth 4 on the coupled bench: the linear "
                                  "bench exact, the remainder by its last four values")
    native: ClassVar[str] = "history"

    def __post_init__(self):
        super().__post_init__()
        whole_number("every", self.every)

    def check_model(self, model) -> None:
        super().check_model(model)
        if model.every != self.every:
            raise ConfigError(f"{self.name}: the model was built for every = {model.every}, the "
                              f"solver has {self.every}; build the model with the solver's every "
                              "(rig.bench.build_model)")

    def advance_bench(self, model, z, native, v):
        """The native state: the remainder at the last ``ETDAB_ORDER`` nodes (newest first,
        one row each); with ``every`` > 1 one more row, the steps since the newest node."""
        self.check_model(model)
        z_out = np.empty((v.size, z.size))
        accel = np.empty(v.size)
        nf = model.coupled.rows.size
        phase = np.zeros(1, dtype=np.int64)
        if native is None:
            hist = np.zeros((ETDAB_ORDER, nf))
        else:
            native = np.array(native, dtype=float)
            hist = np.ascontiguousarray(native[:ETDAB_ORDER])
            if self.every > 1:
                phase[0] = int(native[ETDAB_ORDER, 0])
        kernel = etdab_kernel(*model.etdab[:3], hist.shape[0], model.coupled.n)
        kernel(model.coupled.args(), model.etdab, self.substeps, native is not None, hist,
               phase, v, z, z_out, accel)
        if self.every > 1:
            hist = np.vstack([hist, np.full((1, nf), float(phase[0]))])
        return z_out, accel, hist


# ================================================================================================
# compiled kernels
# ================================================================================================

def etd_ab_weights(a: np.ndarray, rows: np.ndarray, h: float, order: int, lag: int = 0
                   ) -> np.ndarray:
    """Weights of :func:`etd_ab_kernel` with the remainder at every step:
    ``etd_ab_phase_weights(a, rows, h, order, 1, lag)[0][0]``, (order, nf, nz)."""
    return etd_ab_phase_weights(a, rows, h, order, 1, lag)[0][0]


def etd_ab_phase_weights(a: np.ndarray, rows: np.ndarray, h: float, order: int, every: int,
                         lag: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Weights of :func:`etd_ab_kernel` for a remainder evaluated at every ``every``-th step
    (its nodes ``H = every h`` apart): ``(w, lagv)``.

    ``w`` (every, order, nf, nz) (transposed for the kernel's loop): for the step that starts
    ``i`` steps after the newest node, ``W^(i)_j = int_0^h e^{A(h-s)} P L_j((i h + s) / H) ds``,
    where ``P`` puts the remainder's ``nf`` rows into z and ``L_j`` is the Lagrange polynomial
    through the nodes ``x = -lag, .., -(lag + order - 1)`` (in units of H) that is 1 at ``x =
    -(lag + j)``. ``lagv`` (every, order): ``L_j(i / every)``, the remainder at that step's start.
    Read off one matrix exponential of the system augmented by the monomials (Van Loan): block m
    of its first block row is ``int_0^h e^{A(h-s)} P (s/h)^m ds / m!``; ``L_j(i / every + u /
    every)`` is expanded in powers of ``u = s / h`` (``every`` = 1: the powers of ``L_j``'s own
    coefficients, exactly)."""
    nz = np.shape(a)[0]
    nf = rows.size
    _, ks = monomial_integrals(a, rows, h, order)
    nodes = -(lag + np.arange(order, dtype=float))
    poly = np.polynomial.polynomial
    w = np.zeros((every, order, nz, nf))
    lagv = np.zeros((every, order))
    for j in range(order):
        others = np.delete(nodes, j)
        coef = poly.polyfromroots(others) / np.prod(nodes[j] - others)
        for i in range(every):
            if every == 1:
                comp = coef
            else:
                comp = np.zeros(1)
                for m, cm in enumerate(coef):
                    comp = poly.polyadd(comp, cm * poly.polypow([i / every, 1.0 / every], m))
            lagv[i, j] = poly.polyval(i / every, coef)
            for m in range(min(order, comp.size)):
                w[i, j] += comp[m] * ks[m]
    return np.ascontiguousarray(w.transpose(0, 1, 3, 2)), lagv


def etd_ab_sparsity(w: np.ndarray, a_rows: np.ndarray) -> tuple[int, int]:
    """Where :func:`etd_ab_kernel`'s products are not identically zero: ``w_rows``, the rows of
    z the weights reach (a prefix: the source's reconstruction filter, last in z, never sees the
    remainder), and ``a_cols``, the columns of ``a_rows`` in use (a prefix). Skipping exact zeros
    leaves every sum's value unchanged (finite states); it saves ~5 % of a step (skipping
    Phi's zero blocks by ranges per column cost more than it saved: the loops no longer
    vectorise)."""
    rows = np.flatnonzero(np.abs(w).reshape(-1, w.shape[-1]).sum(axis=0))
    cols = np.flatnonzero(np.abs(a_rows).sum(axis=0))
    return int(rows[-1] + 1 if rows.size else 0), int(cols[-1] + 1 if cols.size else 0)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def etd_ab_kernel(prm, mats, nsub, have, hist, phase, v, z, z_out, ax_out):
    """Exponential Adams-Bashforth over len(v) DAC intervals, ``nsub`` steps of h each::

        z_{k+1} = Phi z_k + Gamma v + sum_j W^(i)_j f(z at node n - lag - j),  j = 0 .. order - 1

    (``phi_t`` = Phi transposed and ``gam`` over h; ``w``, ``lagv`` from
    :func:`etd_ab_phase_weights`, ``every`` = len(w), lag = len(hist) - order): the linear
    bench and the held source exactly, the remainder's integral over the step by the polynomial
    through its values at ``order`` past nodes, which are every ``every``-th step; ``i`` is the
    step's place after the newest node (``phase[0]``, in/out: 0 .. every - 1 at the block's
    start). At a node, one evaluation of f at the step's own state, which also gives the
    nonlinear x0''; between nodes x0'' is the linear row plus f's first row interpolated
    (``lagv``). ``ax_out[k]`` = x0'' and ``z_out[k]`` = z at DAC instant k. ``every`` = 1: f at
    every step (with lag >= 1 the step does not wait for the newest evaluation); the
    acquisition's default is :func:`rig.bench.model.remainder_every`.

    ``w_rows, a_cols`` (:func:`etd_ab_sparsity`) skip exact zeros of the products. ``hist``
    (lag + order, nf) holds f at the last nodes (newest first) and is updated; ``have`` False:
    none yet (a start, which is a node: every entry is taken as f(z_0)). ``z`` (in/out) ends at
    the instant len(v). The rows are summed in a fixed order, so block splits reproduce one-shot
    runs bit for bit. Compiled with FMA contraction (``fastmath={"contract"}``, no reordering):
    the acquisition runs the same arithmetic unrolled for the matrices' zero pattern
    (:func:`etdab_kernel`, the same values), this loop is its reference and the
    path of benches too large to unroll."""
    n, two, nz, nf, work, alpha = kernel_scratch(prm, z)
    phi_t, gam, w, lagv, w_rows, a_cols = mats
    dense, bodies, stage = arg_groups(prm)
    g, hc, s, cm, mtot = dense
    th0, q_idx, wc, a_rows = prm.th0, prm.q_idx, prm.wc, prm.a_rows
    every = w.shape[0]
    order = w.shape[1]
    nh = hist.shape[0]
    lag = nh - order
    f = np.empty(nf)
    zn = np.empty(nz)
    zw = np.empty(nz)
    first = not have
    ph = phase[0]
    ax = 0.0
    for kk in range(v.shape[0]):
        vk = v[kk]
        for sub in range(nsub):
            if ph == 0:
                if two:
                    ax = remainder2_fast(g, hc, s, cm, mtot, stage, th0, q_idx, wc, a_rows,
                                         a_cols, z, f)
                else:
                    ax = remainder_n(bodies, g, stage, th0, q_idx, wc, a_rows, z, work, alpha, f)
                if first:
                    first = False
                    for j in range(nh):
                        for i in range(nf):
                            hist[j, i] = f[i]
                else:
                    for j in range(nh - 1, 0, -1):
                        for i in range(nf):
                            hist[j, i] = hist[j - 1, i]
                    for i in range(nf):
                        hist[0, i] = f[i]
            elif sub == 0:
                ax = 0.0
                for col in range(a_cols):
                    ax += a_rows[0, col] * z[col]
                for j in range(order):
                    ax += lagv[ph, j] * hist[lag + j, 0]
            if sub == 0:
                ax_out[kk] = ax
                for r in range(nz):
                    z_out[kk, r] = z[r]
            for r in range(nz):
                zn[r] = gam[r] * vk
                zw[r] = 0.0
            for col in range(nz):
                zc = z[col]
                for r in range(nz):
                    zn[r] += phi_t[col, r] * zc
            for j in range(order - 1, -1, -1):
                for i in range(nf):
                    x = hist[lag + j, i]
                    for r in range(w_rows):
                        zw[r] += w[ph, j, i, r] * x
            for r in range(nz):
                z[r] = zn[r] + zw[r]
            ph += 1
            if ph == every:
                ph = 0
    phase[0] = ph


# ================================================================================================
# the step unrolled for the matrices' exact-zero pattern (what the acquisition runs)
# ================================================================================================
#
# etdab_source writes etd_ab_kernel's step as straight-line code on scalars for the zero pattern
# of its matrices (rig.unrolled: why, and how generated code is cached): the same operations in
# the same order (each sum from its first term in the loop kernel's order, the zero products
# left out, which leaves every finite sum's value unchanged) under the same compiler options, so
# the two give equal values; the unrolled one is faster per step (docs/benchmarks/history.md,
# speed round 4).

#: numba options of the generated etdab kernel: :func:`etd_ab_kernel`'s own
ETDAB_OPTIONS = dict(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
_by_pattern: dict[tuple, object] = {}


def _etdab_step_lines(phi_t: np.ndarray, used: np.ndarray, lag: int, every: int) -> list[str]:
    """The generated loop's step: zn[r] = gam[r] v, then + phi_t[col, r] z[col] for col = 0 ..
    nz - 1; zw[r] from 0.0, + w[ph, j, i, r] hist[lag + j, i] for j = order - 1 .. 0, i = 0 ..
    nf - 1; z = zn + zw (the exact zeros of ``phi_t`` and of the weights, ``used``, left out)."""
    nz = phi_t.shape[0]
    order, nf = used.shape[0], used.shape[1]
    out = []
    for r in range(nz):
        e = f"g{r} * vk"
        for col in range(nz):
            if phi_t[col, r] != 0.0:
                e = f"{e} + p{r}_{col} * z{col}"
        out.append(f"            n{r} = {e}")
    for r in range(nz):
        e = "0.0"
        for j in range(order - 1, -1, -1):
            for i in range(nf):
                if used[j, i, r]:
                    wt = f"w{j}_{i}_{r}" if every == 1 else f"w[ph, {j}, {i}, {r}]"
                    e = f"{e} + {wt} * h{lag + j}_{i}"
        out.append(f"            s{r} = {e}")
    for r in range(nz):
        out.append(f"            z{r} = n{r} + s{r}")
        out.append(f"            z[{r}] = z{r}")
    return out


def etdab_source(phi_t: np.ndarray, gam: np.ndarray, w: np.ndarray, hist_rows: int,
                 two: bool, name: str = "etd_ab_unrolled") -> str:
    """Python source of a function with :func:`etd_ab_kernel`'s signature and
    arithmetic, unrolled for ``phi_t`` (nz, nz), ``gam`` (nz,), ``w`` (every, order, nf, nz)
    and a history of ``hist_rows`` (lag + order) nodes: their values are read at run time, their
    exact zeros are left out of the code (a kernel for this pattern serves any values with the
    same zeros). ``every`` = 1 keeps the weights in locals; ``every`` > 1 (a remainder every
    ``every`` steps) reads the step's phase of them from ``w``. ``two``: the chain has two bodies
    (the dense remainder, inlined), else the O(n) recursion."""
    phi_t, gam, w = (np.asarray(x, dtype=float) for x in (phi_t, gam, w))
    nz = phi_t.shape[0]
    every, order, nf, _ = w.shape
    nh = int(hist_rows)
    lag = nh - order
    if phi_t.shape != (nz, nz) or gam.shape != (nz,) or w.shape[3] != nz or lag < 0:
        raise ValueError(f"shapes do not match: phi_t {phi_t.shape}, gam {gam.shape}, "
                         f"w {w.shape}, hist_rows {nh}")
    used = np.any(w != 0.0, axis=0)  # (order, nf, nz): a product in some phase
    L = []
    put = L.append
    put(f"def {name}(prm, mats, nsub, have, hist, phase, v, z, z_out, ax_out):")
    put(f'    """Generated by rig.solvers.etdab.etdab_source: nz = {nz}, nf = {nf}, '
        f'order = {order}, lag = {lag}, every = {every}."""')
    put("    n, two, nz, nf, work, alpha = kernel_scratch(prm, z)")
    put("    phi_t, gam, w, lagv, w_rows, a_cols = mats")
    put("    dense, bodies, stage = arg_groups(prm)")
    put("    g, hc, s, cm, mtot = dense")
    put("    th0, q_idx, wc, a_rows = prm.th0, prm.q_idx, prm.wc, prm.a_rows")
    put("    f = np.empty(nf)")
    for r in range(nz):
        for col in range(nz):
            if phi_t[col, r] != 0.0:
                put(f"    p{r}_{col} = phi_t[{col}, {r}]")
        put(f"    g{r} = gam[{r}]")
        put(f"    z{r} = z[{r}]")
    if every == 1:
        for j in range(order):
            for i in range(nf):
                for r in range(nz):
                    if used[j, i, r]:
                        put(f"    w{j}_{i}_{r} = w[0, {j}, {i}, {r}]")
    for j in range(nh):
        for i in range(nf):
            put(f"    h{j}_{i} = hist[{j}, {i}]")
    put("    first = not have")
    put("    ph = phase[0]")
    put("    ax = 0.0")
    put("    for kk in range(v.shape[0]):")
    put("        vk = v[kk]")
    put("        for sub in range(nsub):")
    put("            if ph == 0:")
    if two:
        put("                ax = remainder2_fast(g, hc, s, cm, mtot, stage, th0, q_idx, wc,")
        put("                                     a_rows, a_cols, z, f)")
    else:
        put("                ax = remainder_n(bodies, g, stage, th0, q_idx, wc, a_rows, z,")
        put("                                 work, alpha, f)")
    for i in range(nf):
        put(f"                f{i} = f[{i}]")
    put("                if first:")
    put("                    first = False")
    for j in range(nh):
        for i in range(nf):
            put(f"                    h{j}_{i} = f{i}")
    put("                else:")
    for j in range(nh - 1, 0, -1):
        for i in range(nf):
            put(f"                    h{j}_{i} = h{j - 1}_{i}")
    for i in range(nf):
        put(f"                    h0_{i} = f{i}")
    if every > 1:  # between nodes: x0'' from the linear row and f's first row interpolated
        put("            elif sub == 0:")
        put("                ax = 0.0")
        put("                for col in range(a_cols):")
        put("                    ax += a_rows[0, col] * z[col]")
        for j in range(order):
            put(f"                ax += lagv[ph, {j}] * h{lag + j}_0")
    put("            if sub == 0:")
    put("                ax_out[kk] = ax")
    for r in range(nz):
        put(f"                z_out[kk, {r}] = z{r}")
    L.extend(_etdab_step_lines(phi_t, used, lag, every))
    put("            ph += 1")
    put("            if ph == w.shape[0]:")
    put("                ph = 0")
    put("    phase[0] = ph")
    for j in range(nh):
        for i in range(nf):
            put(f"    hist[{j}, {i}] = h{j}_{i}")
    head = ("import numpy as np\n\n"
            "from rig.solvers.coupled import arg_groups, kernel_scratch, remainder2_fast, "
            "remainder_n\n\n\n")
    return head + "\n".join(L) + "\n"


#: :func:`etdab_kernel` unrolls benches of at most this many states (the paper's has 12, a
#: three-body chain 14): the code grows as the square of the states and its compile time with it
#: (~3 s at 12); larger benches, whose step is dominated by the chain's O(n) recursion anyway, use
#: the loop kernel (the same values)
UNROLL_MAX_STATES = 16


def etdab_kernel(phi_t: np.ndarray, gam: np.ndarray, w: np.ndarray, hist_rows: int,
                 n_bodies: int):
    """The compiled etdab kernel for these matrices: unrolled for their sizes and exact-zero
    pattern (generated and compiled once per pattern; memoised in the process by the pattern, so
    a call per block costs a few microseconds), or :func:`etd_ab_kernel` beyond
    :data:`UNROLL_MAX_STATES` states. Either gives the same values."""
    if phi_t.shape[0] > UNROLL_MAX_STATES:
        return etd_ab_kernel
    key = (phi_t.shape, w.shape, int(hist_rows), n_bodies == 2,
           np.packbits(np.asarray(phi_t) != 0.0).tobytes(),
           np.packbits(np.any(np.asarray(w) != 0.0, axis=0)).tobytes())
    got = _by_pattern.get(key)
    if got is None:
        src = etdab_source(phi_t, gam, w, hist_rows, n_bodies == 2)
        got = _by_pattern[key] = load(src, "etd_ab_unrolled", ETDAB_OPTIONS)
    return got
