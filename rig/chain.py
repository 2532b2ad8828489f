"""A planar chain of rigid bodies hanging from a translating base (SPEC section 2).

Conventions
-----------
Angles ``theta_j`` are measured from the downward vertical with ``x = +sin(theta)``. The base (top
pivot) is at ``(x0(t), y0(t))`` and translates without rotating. Body ``j`` (0-based here, 1-based in
SPEC) has its upper joint ``P_{j-1}``, its lower joint ``P_j = P_{j-1} + l_j (sin th_j, -cos th_j)``,
mass ``m_j``, centre of mass at ``c_j`` from its upper joint along the body and inertia ``J_j`` about
its centre of mass. With ``mu_j`` the mass below body ``j``::

    S_j = m_j c_j + l_j mu_j,   D_j = J_j + m_j c_j^2 + l_j^2 mu_j,   H_jj = D_j,  H_jk = l_min S_max
    M(th)_jk = H_jk cos(th_j - th_k),   N(th)_jk = H_jk sin(th_j - th_k)
    M th'' + N th'^2 + C th' + diag(S) [(g + y0'') sin th + x0'' cos th] = 0

``C`` is ``diag(Gamma)`` for absolute damping (a torque ``-Gamma_j th_j'``, as Ishizaki writes it) or
the viscous-joint matrix for relative damping (``-Gamma_j (th_j' - th_{j-1}')`` acting between
neighbours). Everything is SI: kg, m, kg m^2, N m s/rad, m/s^2, rad, rad/s, J.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg

from rig.errors import ConfigError
from rig.jit import njit
from rig.solvers.primitives import cholesky_solve, rhs_rec

G_STANDARD = 9.80665  # m/s^2
DAMPING_MODES = ("absolute", "relative")


def _float_tuple(name: str, values, *, minimum: float | None, strict: bool, n: int | None) -> tuple:
    """Validate a sequence of finite floats; the error names the field, the index and the value."""
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} = {values!r} is invalid: expected a sequence of numbers") from None
    if n is not None and len(out) != n:
        raise ConfigError(f"{name} has {len(out)} entries; expected {n} (one per body)")
    if not out:
        raise ConfigError(f"{name} is empty; a chain needs at least one body")
    for i, v in enumerate(out):
        if not math.isfinite(v):
            raise ConfigError(f"{name} of body {i + 1} = {v} is invalid: expected a finite number")
        if minimum is not None and (v < minimum or (strict and v == minimum)):
            rel = ">" if strict else ">="
            raise ConfigError(f"{name} of body {i + 1} = {v} is invalid: expected {rel} {minimum}")
    return out


@dataclass(frozen=True)
class Chain:
    """Parameters of an n-body planar chain on a moving base (immutable, validated).

    Parameters
    ----------
    mass_kg : masses m_j [kg], > 0.
    length_m : joint-to-joint lengths l_j [m], > 0 (the last body's only places its lower end).
    com_m : centre-of-mass distances c_j from the upper joint along the body [m].
    inertia_kgm2 : inertias J_j about the centre of mass [kg m^2], >= 0 (0 is a point mass).
    damping_nms : viscous damping coefficients Gamma_j [N m s/rad], >= 0.
    damping_mode : ``"absolute"`` (torque on each body against its own angular velocity) or
        ``"relative"`` (a viscous joint: Gamma_j acts on th_j' - th_{j-1}', th_0' = 0).
    g_mps2 : gravitational acceleration [m/s^2], > 0.
    """

    mass_kg: tuple
    length_m: tuple
    com_m: tuple
    inertia_kgm2: tuple
    damping_nms: tuple
    damping_mode: str = "absolute"
    g_mps2: float = G_STANDARD

    def __post_init__(self):
        m = _float_tuple("mass_kg", self.mass_kg, minimum=0.0, strict=True, n=None)
        n = len(m)
        set_ = object.__setattr__
        set_(self, "mass_kg", m)
        set_(self, "length_m", _float_tuple("length_m", self.length_m, minimum=0.0, strict=True, n=n))
        set_(self, "com_m", _float_tuple("com_m", self.com_m, minimum=None, strict=False, n=n))
        set_(self, "inertia_kgm2",
             _float_tuple("inertia_kgm2", self.inertia_kgm2, minimum=0.0, strict=False, n=n))
        set_(self, "damping_nms",
             _float_tuple("damping_nms", self.damping_nms, minimum=0.0, strict=False, n=n))
        if self.damping_mode not in DAMPING_MODES:
            raise ConfigError(f"damping_mode = {self.damping_mode!r} is invalid: expected one of "
                              f"{', '.join(DAMPING_MODES)}")
        g = self.g_mps2
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g) or g <= 0:
            raise ConfigError(f"g_mps2 = {g!r} is invalid: expected a finite number > 0")
        set_(self, "g_mps2", float(g))
        for j, s in enumerate(self.S):
            if not s > 0:
                raise ConfigError(
                    f"com_m of body {j + 1} = {self.com_m[j]} gives S_{j + 1} = m c + l mu = {s:.6g} kg m; the "
                    "hanging equilibrium needs S_j > 0 (centre of mass of everything below joint j "
                    "must hang below it)")

    # -- derived constants (computed once) -------------------------------------------------
    @property
    def n(self) -> int:
        """Number of bodies."""
        return len(self.mass_kg)

    @cached_property
    def mu(self) -> np.ndarray:
        """Mass below each body, mu_j = sum_{i>j} m_i [kg], shape (n,)."""
        m = np.asarray(self.mass_kg)
        return np.concatenate([np.cumsum(m[::-1])[::-1][1:], [0.0]])

    @cached_property
    def S(self) -> np.ndarray:
        """First moments S_j = m_j c_j + l_j mu_j [kg m], shape (n,)."""
        return np.asarray(self.mass_kg) * np.asarray(self.com_m) + np.asarray(self.length_m) * self.mu

    @cached_property
    def D(self) -> np.ndarray:
        """Diagonal inertias D_j = J_j + m_j c_j^2 + l_j^2 mu_j [kg m^2], shape (n,)."""
        m, c, l = (np.asarray(v) for v in (self.mass_kg, self.com_m, self.length_m))
        return np.asarray(self.inertia_kgm2) + m * c**2 + l**2 * self.mu

    @cached_property
    def H(self) -> np.ndarray:
        """Constant inertia matrix H [kg m^2], shape (n, n): H_jj = D_j, H_jk = l_min(j,k) S_max(j,k).

        The mass matrix is ``M(th) = H * cos(th_j - th_k)``; at the hanging equilibrium ``M = H``.
        """
        idx = np.arange(self.n)
        lo = np.minimum.outer(idx, idx)
        hi = np.maximum.outer(idx, idx)
        h = np.asarray(self.length_m)[lo] * self.S[hi]
        np.fill_diagonal(h, self.D)
        return h

    @cached_property
    def C(self) -> np.ndarray:
        """Damping matrix C [N m s/rad], shape (n, n), generalised force ``Q = -C th'``."""
        gam = np.asarray(self.damping_nms)
        if self.damping_mode == "absolute":
            return np.diag(gam)
        c = np.zeros((self.n, self.n))
        for j in range(self.n):  # joint j links body j-1 (or the base) and body j
            c[j, j] += gam[j]
            if j > 0:
                c[j - 1, j - 1] += gam[j]
                c[j, j - 1] -= gam[j]
                c[j - 1, j] -= gam[j]
        return c

    @cached_property
    def K(self) -> np.ndarray:
        """Linear gravitational stiffness g diag(S) [N m/rad], shape (n, n)."""
        return self.g_mps2 * np.diag(self.S)

    # -- nonlinear dynamics ----------------------------------------------------------------
    def mass_matrix(self, theta) -> np.ndarray:
        """M(theta) [kg m^2], shape (..., n, n)."""
        th = np.asarray(theta, dtype=float)
        return self.H * np.cos(th[..., :, None] - th[..., None, :])

    def accelerations(self, theta, omega, ax=0.0, ay=0.0, *, algorithm="dense") -> np.ndarray:
        """Angular accelerations th'' [rad/s^2] for one state, shape (n,).

        ``ax``, ``ay`` are the base accelerations x0'', y0'' [m/s^2] (y up). ``algorithm`` is
        ``"dense"`` (mass matrix and Cholesky, O(n^3): the reference) or ``"recursive"``
        (articulated-body recursion, O(n)); both solve the same equations.
        """
        th = np.asarray(theta, float)
        om = np.asarray(omega, float)
        out = np.empty(self.n)
        if algorithm == "dense":
            work = np.empty((self.n, self.n + 1))
            accel_kernel(self.H, self.S, self.C, self.g_mps2, th, om, float(ax), float(ay), out,
                         work)
        elif algorithm == "recursive":
            out[:] = self._recursive(th, om, ax, ay)[0]
        else:
            raise ConfigError(f"algorithm = {algorithm!r} is invalid: expected 'dense' or "
                              "'recursive'")
        return out

    def body_table(self) -> np.ndarray:
        """The (6, n) body table of the O(n) recursion (:func:`rig.solvers.primitives.rhs_rec`):
        rows mass, length, com, inertia, damping and the relative-damping flag (1.0 or 0.0)."""
        out = np.empty((6, self.n))
        out[0], out[1], out[2], out[3], out[4] = (self.mass_kg, self.length_m, self.com_m,
                                                  self.inertia_kgm2, self.damping_nms)
        out[5] = 1.0 if self.damping_mode == "relative" else 0.0
        return out

    def _recursive(self, theta, omega, ax, ay) -> tuple[np.ndarray, float]:
        """(th'', the horizontal force on the base) by the solvers' O(n) recursion."""
        n = self.n
        y = np.concatenate([np.asarray(theta, float), np.asarray(omega, float)])
        f = np.empty((1, 2 * n))
        force = rhs_rec(self.body_table(), self.g_mps2, y, float(ax), float(ay), f, 0,
                         np.empty((n, 6)))
        return f[0, n:], float(force)

    def base_force(self, theta, omega, ax=0.0, ay=0.0) -> float:
        """Horizontal force the chain exerts on its base [N] (the reaction a stage feels), for
        the state and base accelerations given (O(n) recursion)."""
        return self._recursive(theta, omega, ax, ay)[1]

    def energy(self, theta, omega) -> np.ndarray:
        """Total mechanical energy in the base frame [J]: 1/2 w^T M w - g sum S_j cos th_j.

        Accepts states of shape (n,) or a trajectory (T, n); returns shape () or (T,). With a fixed
        base, dE/dt = -w^T C w.
        """
        th = np.atleast_2d(np.asarray(theta, float))
        om = np.atleast_2d(np.asarray(omega, float))
        out = np.empty(th.shape[0])
        energy_kernel(self.H, self.S, self.g_mps2, th, om, out)
        return out if np.ndim(theta) == 2 else out[0]

    # -- linear model ----------------------------------------------------------------------
    def state_space(self) -> tuple[np.ndarray, np.ndarray]:
        """Linearisation about hanging at rest: z' = A z + B x0'', z = (theta, omega).

        Returns ``A`` (2n, 2n) and ``B`` (2n, 1): the theta rows of B are 0 and the omega rows
        are in [rad/s^2 per m/s^2]. From
        ``H th'' + C th' + g diag(S) th = -S x0''``; the vertical input drops out at first order.
        """
        n = self.n
        hinv_k = np.linalg.solve(self.H, self.K)
        hinv_c = np.linalg.solve(self.H, self.C)
        a = np.zeros((2 * n, 2 * n))
        a[:n, n:] = np.eye(n)
        a[n:, :n] = -hinv_k
        a[n:, n:] = -hinv_c
        b = np.zeros((2 * n, 1))
        b[n:, 0] = np.linalg.solve(self.H, -self.S)
        return a, b

    def frf_angles(self, freqs_hz) -> np.ndarray:
        """Angles per unit base acceleration, Theta(i w) [rad per m/s^2], shape (nf, n).

        Direct complex solve of ``(-w^2 H + i w C + g diag(S)) Theta = -S``. At 0 Hz every
        Theta_j = -1/g (phase 180 deg).
        """
        w = 2 * np.pi * np.atleast_1d(np.asarray(freqs_hz, float))
        z = (self.K[None] - (w**2)[:, None, None] * self.H[None]
             + 1j * w[:, None, None] * self.C[None])
        rhs = np.broadcast_to(-self.S.astype(complex), (w.size, self.n))
        return np.linalg.solve(z, rhs[..., None])[..., 0]

    def point_weights(self, body: int, s_m: float) -> np.ndarray:
        """Weights w with xi = w . theta, the linearised horizontal displacement relative to the base
        of the point at distance ``s_m`` [m] along body ``body`` (0-based) from its upper joint."""
        if not 0 <= body < self.n:
            raise ConfigError(f"body = {body} is invalid: expected 0 <= body < {self.n}")
        if not math.isfinite(s_m):
            raise ConfigError(f"s_m = {s_m} is invalid: expected a finite distance [m]")
        w = np.zeros(self.n)
        w[:body] = np.asarray(self.length_m)[:body]
        w[body] = float(s_m)
        return w

    def frf_point(self, freqs_hz, body: int, s_m: float) -> np.ndarray:
        """Horizontal displacement, relative to the base, of a point on a body per unit base
        acceleration [m per m/s^2], shape (nf,). See :meth:`point_weights`."""
        return self.frf_angles(freqs_hz) @ self.point_weights(body, s_m)

    def natural_frequencies_hz(self) -> np.ndarray:
        """Undamped natural frequencies of the linearised chain [Hz], ascending, shape (n,)."""
        lam = scipy.linalg.eigh(self.K, self.H, eigvals_only=True)
        return np.sqrt(lam) / (2 * np.pi)

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Damped modes of the linearised chain, ascending in frequency.

        Returns (natural frequency |lambda|/2pi [Hz], quality factor Q = |lambda| / (-2 Re lambda)),
        one entry per mode; Q is ``inf`` for an undamped chain. The eigenvalues come from the
        pencil ``[[0, I], [-K, -C]] - lambda [[I, 0], [0, H]]``, which never inverts H (accurate
        also for a nearly singular mass matrix, beta^2 -> 1). Overdamped modes (two real
        eigenvalues) are paired in order, with omega_n = sqrt(l1 l2) and Q = omega_n / -(l1 + l2);
        where H is singular to working precision the massless mode (an infinite eigenvalue and its
        fast real partner) is not reported.
        """
        n = self.n
        a = np.zeros((2 * n, 2 * n))
        a[:n, n:] = np.eye(n)
        a[n:, :n] = -self.K
        a[n:, n:] = -self.C
        b = np.eye(2 * n)
        b[n:, n:] = self.H
        lam = scipy.linalg.eigvals(a, b)
        lam = lam[np.isfinite(lam)]  # H singular to working precision: a massless mode, dropped
        undamped = not np.any(self.C)
        if undamped:  # exactly conservative: the eigenvalues are +-i w; drop round-off real parts
            wn = np.sort(np.abs(lam.imag[lam.imag > 0]))
            return wn / (2 * np.pi), np.full(wn.size, np.inf)
        scale = np.max(np.abs(lam))
        is_real = np.abs(lam.imag) <= 1e-12 * scale
        osc = lam[(~is_real) & (lam.imag > 0)]
        wn = list(np.abs(osc))
        q = [abs(z) / (-2 * z.real) if z.real < 0 else np.inf for z in osc]
        real = np.sort(lam[is_real].real)
        if real.size % 2:  # the partner of one went to infinity with the massless mode
            real = real[1:] if abs(real[0]) >= abs(real[-1]) else real[:-1]  # drop the fastest
        for la, lb in zip(real[0::2], real[1::2]):
            w0 = math.sqrt(la * lb)
            wn.append(w0)
            q.append(w0 / -(la + lb))
        order = np.argsort(wn)
        return np.asarray(wn)[order] / (2 * np.pi), np.asarray(q)[order]

    def antiresonances_hz(self, weights) -> np.ndarray:
        """Undamped anti-resonance frequencies [Hz] of the output ``weights . theta``: the zeros of
        its frequency response, from the bordered generalised eigenproblem
        ``[[K, -b], [w^T, 0]] v = w^2 [[H, 0], [0, 0]] v`` (b = -S). Ascending; only real,
        positive ones (an output may have none)."""
        n = self.n
        w = np.asarray(weights, float)
        big_a = np.zeros((n + 1, n + 1))
        big_a[:n, :n] = self.K
        big_a[:n, n] = self.S  # -b
        big_a[n, :n] = w
        big_b = np.zeros((n + 1, n + 1))
        big_b[:n, :n] = self.H
        lam = scipy.linalg.eigvals(big_a, big_b)
        lam = lam[np.isfinite(lam)]
        scale = np.max(np.abs(np.linalg.eigvals(np.linalg.solve(self.H, self.K))))
        ok = (np.abs(lam.imag) <= 1e-9 * scale) & (lam.real > 0)
        return np.sort(np.sqrt(lam[ok].real)) / (2 * np.pi)


# -- compiled kernels (shared by every integrator) ----------------------------------------

@njit(cache=True)
def accel_kernel(hc, s, cm, g, theta, omega, ax, ay, out, work):
    """th'' of the nonlinear chain into ``out`` (n,); ``work`` is scratch of shape (n, n+1)."""
    n = theta.shape[0]
    m = work[:, :n]
    for j in range(n):
        f = -s[j] * ((g + ay) * math.sin(theta[j]) + ax * math.cos(theta[j]))
        for k in range(n):
            f -= cm[j, k] * omega[k]
        out[j] = f
        m[j, j] = hc[j, j]
    for j in range(n):
        for k in range(j + 1, n):
            d = theta[j] - theta[k]
            hcd = hc[j, k] * math.cos(d)
            hsd = hc[j, k] * math.sin(d)
            m[j, k] = hcd
            m[k, j] = hcd
            out[j] -= hsd * omega[k] * omega[k]  # -N_jk w_k^2
            out[k] += hsd * omega[j] * omega[j]  # -N_kj w_j^2, N antisymmetric
    cholesky_solve(m, out.reshape((1, n)), 0, 0, n)


@njit(cache=True)
def energy_kernel(hc, s, g, theta, omega, out):
    """Energy 1/2 w^T M w - g S.cos(th) for each row of theta, omega (T, n) into out (T,)."""
    t_len, n = theta.shape
    for t in range(t_len):
        e = 0.0
        for j in range(n):
            e += 0.5 * hc[j, j] * omega[t, j] * omega[t, j] - g * s[j] * math.cos(theta[t, j])
            for k in range(j + 1, n):
                e += hc[j, k] * math.cos(theta[t, j] - theta[t, k]) * omega[t, j] * omega[t, k]
        out[t] = e
