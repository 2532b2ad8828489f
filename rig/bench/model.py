"""The bench's model: everything fixed about a run, and its build from a scene.

The state vector (named slices, :attr:`BenchModel.slices`)::

    z = (i [A], x0 [m], v0 [m/s], theta (n) [rad], omega (n) [rad/s], q [m/s], r [V])

``i`` the coil current, ``x0, v0`` the stage, ``theta, omega`` the pendulum, ``q`` the
accelerometer's charge-amplifier high-pass state (absent for a flat-to-DC accelerometer) and ``r``
the states of the source's reconstruction filter (absent when it is off). The input is the source
voltage ``V``, a DAC sample held for one sample interval ``h = 1 / simulation_rate_hz``. The
linear bench is ``z' = A z + B V`` (:meth:`rig.devices.stage.Stage.state_space` plus the
reconstruction filter and the high-pass ``q' = x0'' - w_c q``), and its exact zero-order-hold
step ``z_{k+1} = Phi z_k + Gamma V_k`` (:func:`rig.solvers.exact.discretise`, Van Loan's matrix
exponential). :func:`build_model` also precomputes what the nonlinear path needs: the coupled
kernels' parameters and matrices (lawson4, etdab: :mod:`rig.solvers.coupled`) or the stage-only
exact step at ``h / oversample`` (the prescribed-stage methods rk4, gauss4, dop853, reaction off).
Cost: a few matrix exponentials of the ``(n_states, n_states)`` system per build.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from rig.devices.accelerometer import Accelerometer
from rig.chain import Chain
from rig.errors import ConfigError
from rig.solvers import ExactBench, solver_named
from rig.solvers.coupled import CoupledParams, coupled_params
from rig.solvers.etdab import ETDAB_ORDER, EtdabMatrices, etd_ab_phase_weights, etd_ab_sparsity
from rig.linear import discretise
from rig.solvers.lawson4 import lawson_matrices
from rig.devices.optical_lever import OpticalLever
from rig.scene import Scene
from rig.devices.source import Source
from rig.devices.stage import Stage
from rig.bench.selection import select_model

MODELS = ("auto", "linear", "nonlinear")  # acquisition.model; "auto" resolves to one of the others
NONLINEAR_METHODS = ("lawson4", "etdab", "rk4", "gauss4", "dop853")
COUPLED_METHODS = ("lawson4", "etdab")  # rig.solvers.coupled: the whole bench as one system
DEFAULT_METHOD = "etdab"
PRESCRIBED_STAGE_METHODS = ("rk4", "gauss4", "dop853")  # rig.solvers on a given stage motion


@dataclass(frozen=True, eq=False)
class BenchModel:
    """Everything fixed about a bench run (no state). Build with :func:`build_model`.

    Attributes
    ----------
    scene, source, stage, accelerometer, lever : the parts.
    fs_hz : simulation (DAC) rate [Hz]; decimation : simulation_rate_hz / rate_hz.
    model : "linear" or "nonlinear" (what runs; ``acquisition.model`` may say "auto");
    method, oversample, substeps, rtol, atol : the nonlinear path's integrator settings (method
        name, sub-instants per DAC interval (prescribed-stage methods), steps per DAC interval
        (lawson4) or per sub-interval, dop853 tolerances).
    selection : the model choice of ``acquisition.model = "auto"`` (:func:`select_model`), else
        None (computed on demand by :meth:`BenchSimulation.model_info`).
    a, b : continuous bench ``z' = a z + b V``; phi, gamma : its exact ZOH step at 1 / fs.
    accel_row : x0'' = accel_row . z.  slices : named slices of z.
    stage_phi, stage_gamma, stage_accel_row : prescribed-stage nonlinear path only: the stage +
        accelerometer (z_s = (i, x0, v0, q)) stepped exactly at 1 / (fs oversample).
    coupled, lawson : lawson4 and etdab paths: the kernels' parameters (:class:`rig.solvers.coupled.
        CoupledParams`); lawson4: (E_h, E_h/2, G_h, G_h/2) at h = 1 / (fs substeps).
    etdab : etdab path only: (Phi^T, Gamma, W, L) at h = 1 / (fs substeps), the remainder
        every ``every`` steps (:func:`rig.solvers.etdab.etd_ab_phase_weights`), and their sparsity
        (:func:`rig.solvers.etdab.etd_ab_sparsity`): the kernel's arguments after ``coupled``'s.
    """

    scene: Scene
    source: Source
    stage: Stage
    accelerometer: Accelerometer
    lever: OpticalLever
    fs_hz: float
    decimation: int
    model: str
    method: str
    oversample: int
    substeps: int
    every: int
    rtol: float
    atol: float
    a: np.ndarray
    b: np.ndarray
    phi: np.ndarray
    gamma: np.ndarray
    accel_row: np.ndarray
    slices: dict
    stage_phi: np.ndarray | None = None
    stage_gamma: np.ndarray | None = None
    stage_accel_row: np.ndarray | None = None
    coupled: CoupledParams | None = None
    lawson: tuple | None = None
    selection: dict | None = None
    etdab: EtdabMatrices | None = None

    @property
    def chain(self) -> Chain:
        """The pendulum."""
        return self.scene.chain

    @functools.cached_property
    def solver(self):
        """The solver this model runs (:mod:`rig.solvers`): the exact linear bench for the linear
        model, else ``method`` at ``substeps`` steps per DAC interval (lawson4, etdab: the
        coupled bench) or per sub-interval (the prescribed-stage methods; dop853 at ``rtol``,
        ``atol``)."""
        if self.model == "linear":
            return ExactBench()
        return solver_named(self.method, substeps=self.substeps, every=self.every,
                            rtol=self.rtol, atol=self.atol)

    @property
    def n_states(self) -> int:
        """Length of the bench state vector z."""
        return self.a.shape[0]

    def state_names(self) -> list[str]:
        """Names (with units) of the entries of z."""
        n = self.chain.n
        names = (["coil_current_a", "stage_disp_m", "stage_vel_mps"]
                 + [f"theta{j + 1}_rad" for j in range(n)]
                 + [f"omega{j + 1}_rad_s" for j in range(n)])
        if self.accelerometer.n_states:
            names.append("accel_highpass_q_mps")
        nr = self.n_states - len(names)
        names += [f"reconstruction{k + 1}_v" for k in range(nr)]
        return names


def _bench_state_space(stage: Stage, chain: Chain, acc: Accelerometer, with_chain: bool,
                       source: Source):
    """Continuous (a, b, accel_row, slices) of the source's reconstruction filter + stage
    [+ pendulum] + accelerometer high-pass, input the DAC voltage."""
    ss = stage.state_space(chain if with_chain else None)
    recon = source.reconstruction_state_space()
    nz0 = ss.a.shape[0]
    nq = acc.n_states
    nr = 0 if recon is None else recon[0].shape[0]
    nz = nz0 + nq + nr
    a = np.zeros((nz, nz))
    b = np.zeros((nz, 1))
    a[:nz0, :nz0] = ss.a
    if recon is None:
        b[:nz0] = ss.b
    else:  # the amplifier sees the filter's output c . r; the DAC feeds the filter
        ra, rb, rc = recon
        r = slice(nz0 + nq, nz)
        a[r, r] = ra
        b[r, 0] = rb
        a[:nz0, r] = np.outer(ss.b[:, 0], rc)
    accel_row = np.zeros(nz)
    accel_row[:nz0] = ss.accel_row
    if nq:
        a[nz0, :] = accel_row  # q' = x0'' - w_c q
        a[nz0, nz0] = -acc.corner_rad_s
    slices = {"coil_current_a": slice(0, 1), "stage_disp_m": slice(1, 2),
              "stage_vel_mps": slice(2, 3)}
    if with_chain:
        n = chain.n
        slices["theta_rad"] = slice(3, 3 + n)
        slices["omega_rad_s"] = slice(3 + n, 3 + 2 * n)
    if nq:
        slices["accel_highpass_q_mps"] = slice(nz0, nz0 + 1)
    if nr:
        slices["reconstruction_v"] = slice(nz0 + nq, nz)
    return a, b, accel_row, slices


#: etdab's remainder nodes at least this many per period of the highest frequency it carries
NODES_PER_PERIOD = 16
#: the steps between remainder nodes that :func:`remainder_every` chooses from (10 is not: a
#: sine at the 2.48 Hz mode, 0.3 V, angles to 0.14 rad, erred by 2.8e-5 there against 1.8e-6 at
#: 5 and 3.2e-9 at every step)
EVERY_CHOICES = (5, 2, 1)
#: nodes further apart only for a weak nonlinearity: the predicted linearisation error's upper
#: estimate (:func:`select_model`) at most this (the paper's drive: 6.5e-3; a double rod swinging
#: from 1 rad, whose remainder is as large as the motion and carries its harmonics, erred by
#: 6e-3 in energy over 10 s with nodes every 5 steps)
WEAK_NONLINEARITY = 0.1


def remainder_every(scene: Scene, fs_hz: float, substeps: int = 1,
                    selection: dict | None = None) -> int:
    """etdab's default steps between remainder evaluations for this scene: 1 unless the
    nonlinearity is weak (:data:`WEAK_NONLINEARITY`, from ``selection`` or
    :func:`select_model`); then the largest of :data:`EVERY_CHOICES` whose nodes come at least
    :data:`NODES_PER_PERIOD` times per period of the highest frequency the remainder carries:
    the drive's (``fmax_hz`` of the noise and chirp types, the sine's ``frequency_hz``; a
    burst's switching is broadband: every step) or the chain's highest mode. A weak remainder
    carries those bands (its power above 20 Hz is ~1e-6 of it on the paper's 12.5 Hz noise,
    benchmarks/remainder_spectrum.py), so its polynomial through nodes that far apart is
    accurate: on the paper's drive the remainder every 5 steps errs by 3.9e-9 of the angles' rms
    (6.7e-12 at every step), measured and estimated alike (Richardson, which every run file
    records; tests/rig/solvers/test_coupled_etdab.py)."""
    source = scene.source
    if source.type == "burst-random":
        return 1
    if selection is None:
        selection = select_model(scene)
    if not selection["predicted_linear_error_upper"] <= WEAK_NONLINEARITY:
        return 1
    top = source.frequency_hz if source.type == "sine" else source.fmax_hz
    top = max(top, float(np.max(scene.chain.modes()[0])))
    rate = fs_hz * substeps
    for r in EVERY_CHOICES:
        if r * NODES_PER_PERIOD * top <= rate:
            return r
    return 1


def linear_scene(scene: Scene) -> Scene:
    """``scene`` with the linear acquisition model (``acquisition.model = "linear"``: the bench's
    exact linear step), as every analytic response of the bench uses it."""
    return scene.with_acquisition(model="linear")


def build_model(scene: Scene, *, method: str | None = None, oversample: int = 8,
                substeps: int = 1, every: int | None = None, rtol: float = 1e-10,
                atol: float = 1e-12, selection: dict | None = None) -> BenchModel:
    """Validate the scene's bench sections and build the :class:`BenchModel`.

    ``acquisition.model = "auto"`` runs :func:`select_model` (or takes ``selection``, its
    result for this scene). ``method`` (default ``"etdab"``), ``oversample``, ``substeps``,
    ``rtol``, ``atol`` matter for the nonlinear model only (:mod:`rig.bench`): ``substeps``
    Lawson steps per DAC interval, or for the prescribed-stage methods ``oversample`` exact
    stage-acceleration instants per DAC interval (the pendulum sees them linearly interpolated)
    and ``substeps`` integrator steps per sub-interval; ``every``: etdab evaluates its remainder
    at every ``every``-th step only (:func:`rig.solvers.etdab.etd_ab_phase_weights`; 1: every step;
    None, the default: :func:`remainder_every` for this drive).

    Raises
    ------
    ConfigError : a bad value in ``source``, ``stage``, ``accelerometer``, ``psd`` or
        ``acquisition`` (naming the key, the value and what is valid), or a prescribed-stage
        method with the stage reaction.
    """
    if not isinstance(scene, Scene):
        raise ConfigError(f"scene = {scene!r} is invalid: expected a rig.scene.Scene")
    acq = scene.acquisition
    fs, decimation = acq.simulation_rate_hz, acq.decimation
    source, stage, acc, lever = scene.source, scene.stage, scene.accelerometer, scene.lever
    model = acq.model
    if method is None:
        method = DEFAULT_METHOD
    if method not in NONLINEAR_METHODS:
        raise ConfigError(f"method = {method!r} is invalid: expected one of "
                          f"{', '.join(NONLINEAR_METHODS)}")
    settings = (("oversample", oversample), ("substeps", substeps), ("every", every))
    for name, v in settings:
        if name == "every" and v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"{name} = {v!r} is invalid: expected an integer >= 1")
    if model == "auto":
        if selection is None:
            selection = select_model(scene)
        model = selection["chosen"]
    else:
        selection = None
    if every is None:
        every = (remainder_every(scene, fs, substeps, selection)
                 if model == "nonlinear" and method == "etdab" else 1)
    if model == "nonlinear" and stage.reaction and method in PRESCRIBED_STAGE_METHODS:
        raise ConfigError(
            f"method = {method!r} is not supported with stage.reaction = true: it integrates the "
            "nonlinear pendulum on a prescribed stage motion, so the pendulum cannot load the "
            "stage. Use method 'lawson4' (the coupled nonlinear bench) or set "
            "stage.reaction = false")
    chain = scene.chain
    a, b, accel_row, slices = _bench_state_space(stage, chain, acc, with_chain=True,
                                                 source=source)
    h = 1.0 / fs
    phi, g0, _ = discretise(a, b, h, "zoh")
    kw = {}
    if model == "nonlinear" and method in COUPLED_METHODS:
        q_idx = slices["accel_highpass_q_mps"].start if acc.n_states else -1
        prm = coupled_params(chain, stage, a, q_idx=q_idx,
                              wc=acc.corner_rad_s if acc.n_states else 0.0)
        if method == "lawson4":
            kw = dict(coupled=prm, lawson=lawson_matrices(a, b, h / substeps))
        else:
            hs = h / substeps
            phi_s, g_s, _ = discretise(a, b, hs, "zoh")
            phi_t = np.ascontiguousarray(phi_s.T)
            w, lagv = etd_ab_phase_weights(a, prm.rows, hs, ETDAB_ORDER, every)
            kw = dict(coupled=prm, etdab=EtdabMatrices(phi_t, np.ascontiguousarray(g_s[:, 0]), w,
                                                       lagv, *etd_ab_sparsity(w, prm.a_rows)))
    elif model == "nonlinear":
        sa, sb, srow, _ = _bench_state_space(stage, chain, acc, with_chain=False, source=source)
        sphi, sg0, _ = discretise(sa, sb, h / oversample, "zoh")
        kw = dict(stage_phi=np.ascontiguousarray(sphi), stage_gamma=np.ascontiguousarray(sg0[:, 0]),
                  stage_accel_row=srow)
    return BenchModel(scene=scene, source=source, stage=stage, accelerometer=acc, lever=lever,
                      fs_hz=fs, decimation=decimation, model=model, method=method,
                      oversample=int(oversample), substeps=int(substeps), every=int(every),
                      rtol=float(rtol),
                      atol=float(atol), a=a, b=b, phi=np.ascontiguousarray(phi),
                      gamma=np.ascontiguousarray(g0[:, 0]), accel_row=accel_row, slices=slices,
                      selection=selection, **kw)
