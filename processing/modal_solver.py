"""The solver of :func:`processing.modal.fit_modes`: variable projection.

Solver
------
Variable projection: for every trial ``(f_r, Q_r)`` the residues and the residual polynomial,
which enter linearly, are solved by weighted linear least squares, and Levenberg-Marquardt
(Marquardt's diagonal scaling, Kaufman's Jacobian of the projected residual) moves only the
``2 M`` nonlinear parameters, as ``v = logit((f - f_lo) / (f_hi - f_lo))`` and
``u = logit((Q - 1/2) / Q_max)``: modes stay in the band and underdamped without bounds, and Q
below ``Q_max = 1000 pi f_hi / df`` (at least ten times the start), the Q of a decay over a
thousand records, which no fit can tell from an undamped mode. It stops when the Gauss-Newton
decrement is below ``1e-12`` of chi^2 (parameters then within ~1e-6 of their standard deviation
of the minimum). The minimum is that of the full problem, in a few iterations
(docs/modal-fit-calibration.md).
"""

from __future__ import annotations

import math

import numpy as np

from processing.modal_model import mode_pole_derivs


def real_stack(z: np.ndarray) -> np.ndarray:
    """``z``'s real parts stacked over its imaginary parts along the first axis: a complex
    least-squares problem as a real one of twice the rows."""
    return np.concatenate([z.real, z.imag], axis=0)


def _expit(x):
    """The logistic function ``1 / (1 + exp(-x))``, accurate also for large negative ``x``."""
    e = np.exp(-np.abs(x))
    return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


class LineModel:
    """The modal model on the fitted lines, from one of the term models: for poles ``z_r`` the
    terms ``a_r, b_r`` (and ``d a_r / d z_r``, ``d b_r / d conj(z_r)``) give
    ``H = sum_r [c_r a_r + conj(c_r) b_r] + P``, linear in ``c`` and ``P``'s coefficients."""

    def __init__(self, terms, basis: np.ndarray, m: int, domain: str, fs: float | None):
        self.terms, self.basis, self.m, self.domain, self.fs = terms, basis, m, domain, fs

    def poles(self, fq: np.ndarray):
        """``z_r`` and ``d z_r / d f_r``, ``d z_r / d Q_r`` for (m, 2) ``(f, Q)``."""
        z = np.empty(self.m, complex)
        dz = np.empty((self.m, 2), complex)
        for r, (fr, q) in enumerate(fq):
            p, dpf, dpq = mode_pole_derivs(float(fr), float(q))
            if self.domain == "z":
                z[r] = np.exp(p / self.fs)
                dz[r] = (z[r] * dpf / self.fs, z[r] * dpq / self.fs)
            else:
                z[r] = p
                dz[r] = (dpf, dpq)
        return z, dz

    def design(self, fq: np.ndarray, *, jac: bool):
        """The linear design matrix (n, n_lin) for ``[Re c_r, Im c_r, ..., Re a_j, Im a_j]`` and,
        with ``jac``, the terms and pole derivatives."""
        z, dz = self.poles(fq)
        a, b, da, db = self.terms(z, jac=jac)
        n = self.basis.shape[0]
        cols = np.empty((n, 2 * self.m + 2 * self.basis.shape[1]), complex)
        cols[:, 0:2 * self.m:2] = (a + b).T
        cols[:, 1:2 * self.m:2] = 1j * (a - b).T
        cols[:, 2 * self.m::2] = self.basis
        cols[:, 2 * self.m + 1::2] = 1j * self.basis
        return cols, (z, dz, da, db)

    def mode_derivs(self, c: np.ndarray, extra) -> np.ndarray:
        """d H / d (f_r, Q_r), complex (n, 2 m), for residues ``c``."""
        _, dz, da, db = extra
        out = np.empty((self.basis.shape[0], 2 * self.m), complex)
        for r in range(self.m):
            for i in range(2):
                out[:, 2 * r + i] = c[r] * da[r] * dz[r, i] + np.conj(c[r]) * db[r] * \
                    np.conj(dz[r, i])
        return out

    def full(self, params: np.ndarray):
        """Model and complex Jacobian (n, n_params) in the order of :attr:`ModalFit.params`."""
        m = self.m
        fq = params[:2 * m].reshape(m, 2)
        beta = params[2 * m:]
        cols, extra = self.design(fq, jac=True)
        c = beta[0:2 * m:2] + 1j * beta[1:2 * m:2]
        return cols @ beta, np.concatenate([self.mode_derivs(c, extra), cols], axis=1)


def varpro(model: LineModel, h: np.ndarray, sigma: np.ndarray, starts: np.ndarray, lo: float,
           span: float, q_max: float, *, max_iter: int = 200):
    """Weighted least squares by variable projection: the residues and the residual polynomial
    are solved linearly for every trial ``(f, Q)``, which Levenberg-Marquardt (Kaufman's
    Jacobian of the projected residual) moves in ``v = logit((f - lo) / span)``,
    ``u = logit((Q - 1/2) / q_max)`` (``Q - 1/2 ~ q_max e^u`` below ``q_max``): modes stay in the
    band, underdamped, with ``Q < q_max``. Returns ``(f, Q)`` (m, 2), the linear parameters, the
    iterations and whether it converged."""
    m = model.m
    y = real_stack(h / sigma)
    yy = float(y @ y)

    def to_fq(x):
        fq = np.empty((m, 2))
        fq[:, 0] = lo + span * _expit(x[0::2])
        fq[:, 1] = 0.5 + q_max * _expit(x[1::2])
        return fq

    def evaluate(x):
        fq = to_fq(x)
        cols, extra = model.design(fq, jac=True)
        aw = real_stack(cols / sigma[:, None])
        qm, rm = np.linalg.qr(aw)
        try:
            beta = np.linalg.solve(rm, qm.T @ y)
        except np.linalg.LinAlgError:
            beta = np.linalg.lstsq(aw, y, rcond=None)[0]
        res = y - aw @ beta
        c = beta[0:2 * m:2] + 1j * beta[1:2 * m:2]
        dv = real_stack(model.mode_derivs(c, extra) / sigma[:, None])
        jac = -(dv - qm @ (qm.T @ dv))  # Kaufman: -P_perp (dA/dtheta) beta
        e = _expit(x[0::2])
        jac[:, 0::2] *= span * e * (1.0 - e)
        jac[:, 1::2] *= (fq[:, 1] - 0.5) * (1.0 - _expit(x[1::2]))
        return float(res @ res), res, jac, beta

    x = np.empty(2 * m)
    frac = np.clip((starts[:, 0] - lo) / span, 1e-9, 1 - 1e-9)
    x[0::2] = np.log(frac / (1.0 - frac))
    qf = np.clip((starts[:, 1] - 0.5) / q_max, 1e-300, 1 - 1e-9)
    x[1::2] = np.log(qf / (1.0 - qf))
    cost, res, jac, beta = evaluate(x)
    mu, nu = None, 2.0
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        g = jac.T @ res
        a = jac.T @ jac
        dscale = np.maximum(np.diag(a), 1e-300)
        try:  # the Gauss-Newton decrement: what is left to gain, to second order
            left = float(g @ np.linalg.solve(a, g))
        except np.linalg.LinAlgError:
            left = math.inf
        if left <= 1e-12 * cost + 1e-24 * yy:  # (the second term: round-off of a zero residual)
            converged = True
            break
        if mu is None:
            mu = 1e-3  # relative to each diagonal element (Marquardt's scaling)
        try:
            step = np.linalg.solve(a + mu * np.diag(dscale), -g)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        if np.max(np.abs(step)) < 1e-13 * (1.0 + np.max(np.abs(x))):
            converged = True  # no further decrease within round-off
            break
        x_new = x + step
        cost_new, res_new, jac_new, beta_new = evaluate(x_new)
        if cost_new < cost:
            predicted = -(step @ g) - 0.5 * step @ a @ step
            gain = (cost - cost_new) / (2.0 * predicted) if predicted > 0 else 0.0
            x, cost, res, jac, beta = x_new, cost_new, res_new, jac_new, beta_new
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
    return to_fq(x), beta, it, converged


# -- rotation isolation ----------------------------------------------------------------------
