"""Synthetic measurements of an exact sampled linear system, for the analyzer's tests.

:func:`simulate` runs ``z[n+1] = Phi z[n] + Gamma u[n]``, ``y = C z`` of a
:class:`rig.linear.SampledSystem` exactly (one first-order complex recursion per eigenvalue of
``Phi``, :func:`scipy.signal.lfilter`, which keeps lightly damped poles exact, unlike polynomial
``ss2tf`` forms); :func:`simulate_records` draws a white held input, starts from the stationary
state (no transient) and adds white output noise. The same seed gives the same arrays.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def simulate(system, u, z0=None) -> np.ndarray:
    """Outputs ``y[n] = C z[n]``, ``n = 0 .. len(u)-1``, for input samples ``u[n]`` held over
    ``[n T, (n+1) T)``, from state ``z0`` (default 0); shape ``(n_out, len(u))``."""
    from scipy.signal import lfilter

    u = np.asarray(u, dtype=float)
    nz = system.phi.shape[0]
    z0 = np.zeros(nz) if z0 is None else np.asarray(z0, dtype=float)
    lam, v = np.linalg.eig(system.phi)
    vinv = np.linalg.inv(v)
    gm = vinv @ system.gamma[:, 0]
    q0 = vinv @ z0
    cv = system.c @ v
    y = np.zeros((system.c.shape[0], u.size))
    for r in range(nz):
        if lam[r].imag < 0:
            continue  # the conjugate partner carries it (factor 2 below)
        q, _ = lfilter([0.0, gm[r]], [1.0, -lam[r]], u.astype(complex), zi=[q0[r]])
        fac = 2.0 if lam[r].imag > 0 else 1.0
        y += fac * np.real(np.outer(cv[:, r], q))
    return y


def simulate_records(system, *, n_records: int, n_samples: int, seed: int,
                     input_std: float = 1.0, output_noise: Mapping | None = None,
                     input_name: str = "a") -> dict:
    """A synthetic measurement: white input ``u[n] ~ N(0, input_std^2)`` held over each sample and
    recorded as it is (channel ``input_name``), the exact response from a stationary state, plus
    independent white noise of standard deviation ``output_noise[name]``; one continuous run cut
    into ``n_records`` contiguous records: ``{name: (n_records, n_samples)}``."""
    n_records, n_samples = int(n_records), int(n_samples)
    if n_records < 1 or n_samples < 2:
        raise ValueError(f"n_records = {n_records}, n_samples = {n_samples}: expected >= 1, >= 2")
    rng = np.random.default_rng(seed)
    p = system.stationary_covariance(input_std**2)
    lam, vec = np.linalg.eigh(0.5 * (p + p.T))
    z0 = vec @ (np.sqrt(np.clip(lam, 0.0, None)) * rng.standard_normal(lam.size))
    u = input_std * rng.standard_normal(n_records * n_samples)
    y = simulate(system, u, z0)
    noise = dict(output_noise or {})
    out = {input_name: u.reshape(n_records, n_samples)}
    for i, name in enumerate(system.outputs):
        yi = y[i]
        sd = float(noise.pop(name, 0.0))
        if sd:
            yi = yi + sd * rng.standard_normal(yi.size)
        out[name] = yi.reshape(n_records, n_samples)
    if noise:
        raise ValueError(f"output_noise names {sorted(noise)} are not outputs {system.outputs}")
    return out
