"""Second-order-sections IIR filters with carried state, shared by every layer (the
acquisition's anti-alias filter, the bench's fused chain, the live view's stage position):
scipy.signal.sosfilt's arithmetic, compiled, without importing scipy.signal (~1 s).

:func:`sosfilt_inplace` filters whole rows and :func:`sos_sample` one sample; sections are rows
``[b0, b1, b2, 1, a1, a2]`` in transposed direct form II. :func:`lift_sections` lifts a cascade
to ``q`` samples (its exact linear map over an interval, in the sections' own state
coordinates: ``s_{j+1} = A s_j + M x_j``, ``y_j = C s_j + D x_j[0]``) and
:func:`lifted_sections_pass` runs three channels through that map, computing only every
``q``-th output: equal to filtering every sample and keeping every ``q``-th up to round-off
(the sums in another order; the bound: tests/rig/bench/test_fused.py).

Public API: :func:`sosfilt_inplace`, :func:`sos_sample`, :class:`LiftedSections`,
:func:`lift_sections`, :func:`lifted_sections_pass`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rig.jit import njit


@njit(cache=True, nogil=True)
def sos_sample(sos, zi, ch, cur):
    """One sample ``cur`` of channel ``ch`` through the sections ``sos`` (rows ``[b0, b1, b2, 1,
    a1, a2]``), transposed direct form II, updating ``zi[:, ch, :]``; returns the output. For
    kernels that interleave channels sample by sample; :func:`sosfilt_inplace`
    filters whole rows with the same arithmetic."""
    for s in range(sos.shape[0]):
        new = sos[s, 0] * cur + zi[s, ch, 0]
        zi[s, ch, 0] = sos[s, 1] * cur - sos[s, 4] * new + zi[s, ch, 1]
        zi[s, ch, 1] = sos[s, 2] * cur - sos[s, 5] * new
        cur = new
    return cur


@njit(cache=True, nogil=True)
def sosfilt_inplace(sos, x, zi):
    """Filter every row of ``x`` (channels, samples) in place through the sections ``sos``
    (rows ``[b0, b1, b2, 1, a1, a2]``), transposed direct form II, updating ``zi`` (sections,
    channels, 2): the arithmetic of ``scipy.signal.sosfilt`` in the same order (equal to it bit for
    bit, tests/test_antialias.py) without importing scipy.signal (~1 s)."""
    # the same arithmetic as sos_sample, written out: calling it here measured 1.6-1.8x slower
    # (3 channels x 1e6 samples, 12th order, 15 interleaved rounds: 43 ms against 27 ms)
    n_sec = sos.shape[0]
    for c in range(x.shape[0]):
        for k in range(x.shape[1]):
            cur = x[c, k]
            for s in range(n_sec):
                new = sos[s, 0] * cur + zi[s, c, 0]
                zi[s, c, 0] = sos[s, 1] * cur - sos[s, 4] * new + zi[s, c, 1]
                zi[s, c, 1] = sos[s, 2] * cur - sos[s, 5] * new
                cur = new
            x[c, k] = cur


class LiftedSections(NamedTuple):
    """A cascade of sections lifted to ``q`` samples (:func:`lift_sections`): ``a`` (ns, ns)
    = A, ``m_t`` (q, ns) = M^T, ``c`` (ns,) = C, ``d`` (1,) = D, with ns = 2 x sections (0: no
    filter, the input passed through)."""

    a: np.ndarray
    m_t: np.ndarray
    c: np.ndarray
    d: np.ndarray


def lift_sections(sos: np.ndarray, q: int) -> LiftedSections:
    """The sections ``sos`` lifted to ``q`` samples, in their own state coordinates (``zi`` of
    every section, ``2 x sections`` states ``s``): ``s_{j+1} = A s_j + M x_j`` over an
    interval's q inputs ``x_j`` and the kept output ``y_j = C s_j + D x_j[0]`` (the filtered
    sample at the interval's first instant). Built by running the sections
    (:func:`sos_sample`) on unit states and inputs, so they are the sections' own linear map.
    ``sos`` of shape (0, 6): no filter."""
    sos = np.ascontiguousarray(sos, dtype=float).reshape(-1, 6)
    ns = 2 * sos.shape[0]

    def run(s0, x):
        zi = s0.reshape(-1, 1, 2).copy()
        ys = [sos_sample(sos, zi, 0, xi) for xi in x]
        return zi.reshape(-1), ys[0]

    a, c = np.zeros((ns, ns)), np.zeros(ns)
    for k in range(ns):
        e = np.zeros(ns)
        e[k] = 1.0
        a[:, k], c[k] = run(e, np.zeros(q))
    m = np.zeros((ns, q))
    for i in range(q):
        x = np.zeros(q)
        x[i] = 1.0
        m[:, i], y0 = run(np.zeros(ns), x)
        if i == 0:
            d = np.array([y0])
    band = np.arange(ns)[None, :] >= 2 * (np.arange(ns)[:, None] // 2) + 2
    if np.any(a[band] != 0):  # what the kernel skips: a cascade cannot feed back
        raise ValueError("the lifted sections are not block lower triangular")
    return LiftedSections(np.ascontiguousarray(a), np.ascontiguousarray(m.T), c, d)


@njit(cache=True, nogil=True)
def lifted_sections_pass(xin, sections, s_aa, volts, j0):
    """Three channels through the lifted ``sections`` (:class:`LiftedSections`) over the
    filter inputs ``xin`` (3, q, nj) of intervals ``j0 .. j0 + nj - 1``: writes their kept
    outputs (3, J) at those columns of ``volts``; ``s_aa`` (3, ns) in/out the sections' states
    per channel. Every sum runs per interval in a fixed order."""
    aa, am_t, ac, ad = sections
    q = xin.shape[1]
    nj = xin.shape[2]
    ns = s_aa.shape[1]
    if ns == 0:
        for ch in range(3):
            for j in range(nj):
                volts[ch, j0 + j] = xin[ch, 0, j]
        return
    ua = np.zeros((3, ns, nj))
    for ch in range(3):
        for i in range(q):
            for k in range(ns):
                g = am_t[i, k]
                for j in range(nj):
                    ua[ch, k, j] += g * xin[ch, i, j]
    # the three channels' recursions side by side (independent sums in flight together)
    sn = np.empty((ns, 3))
    sk = np.empty((ns, 3))
    for k in range(ns):
        for ch in range(3):
            sn[k, ch] = s_aa[ch, k]
    d = ad[0]
    for j in range(nj):
        y0 = d * xin[0, 0, j]
        y1 = d * xin[1, 0, j]
        y2 = d * xin[2, 0, j]
        for k in range(ns):
            ck = ac[k]
            y0 += ck * sn[k, 0]
            y1 += ck * sn[k, 1]
            y2 += ck * sn[k, 2]
        volts[0, j0 + j] = y0
        volts[1, j0 + j] = y1
        volts[2, j0 + j] = y2
        for k in range(ns):
            s0 = ua[0, k, j]
            s1 = ua[1, k, j]
            s2 = ua[2, k, j]
            # a cascade: section k // 2 depends on itself and the sections before it only
            # (A is block lower triangular, exact zeros beyond)
            for c in range(2 * (k // 2) + 2):
                akc = aa[k, c]
                s0 += akc * sn[c, 0]
                s1 += akc * sn[c, 1]
                s2 += akc * sn[c, 2]
            sk[k, 0] = s0
            sk[k, 1] = s1
            sk[k, 2] = s2
        for k in range(ns):
            for ch in range(3):
                sn[k, ch] = sk[k, ch]
    for k in range(ns):
        for ch in range(3):
            s_aa[ch, k] = sn[k, ch]
