"""Chains and checks shared by the integrator tests (imported by test modules: pytest puts this
directory on sys.path)."""

import math

import numpy as np

from rig.chain import G_STANDARD, Chain
from rig.simulate import BaseInput, simulate


def rod_chain(n, *, damping=0.0, mode="relative"):
    """Takeno's uniform rods: 1 m, 1 kg/m (m = 1, l = 1, c = 0.5, J = 1/12)."""
    return Chain((1.0,) * n, (1.0,) * n, (0.5,) * n, (1 / 12,) * n, (damping,) * n, mode)


def paper_pendulum():
    """Ishizaki et al. (2009) double pendulum, Gamma from Q1 = 530, Q2 = 100 (SPEC section 4),
    written out (not the scene's preset, so a change there cannot move these tests)."""
    g = G_STANDARD
    m1, m2 = 0.05313525166369857, 0.046864748336301436
    l1 = r1 = 0.02899
    r2, l2 = 0.000846, 0.075
    j1, j2 = 3.320489853900383e-05, 1.4373560955150043e-05
    i1, i2 = j1 + m1 * r1**2, j2 + m2 * r2**2
    gamma1 = 2 / (2 * 530) * math.sqrt((i1 + m2 * l1**2) * (m1 * g * r1 + m2 * g * l1))
    gamma2 = 2 / (2 * 100) * math.sqrt(i2 * m2 * g * r2)
    return Chain((m1, m2), (l1, l2), (r1, r2), (j1, j2), (gamma1, gamma2), "absolute", g)


def random_chain(rng, n, mode):
    m = rng.uniform(0.05, 2.0, n)
    length = rng.uniform(0.05, 1.0, n)
    com = length * rng.uniform(0.1, 0.9, n)
    inertia = m * length**2 * rng.uniform(0.0, 0.2, n)
    return Chain(tuple(m), tuple(length), tuple(com), tuple(inertia),
                 tuple(rng.uniform(0.0, 0.3, n)), mode)


def blockwise_and_one_shot(splits, *, vertical=True, **kw):
    """The damped double rod from (1.0, -0.5) rad on 5 s of seeded random base input (horizontal,
    and vertical unless ``vertical`` is False; 0.01 s samples), run once and in blocks of input
    samples ``splits`` (each block continuing from the previous one's final state). Returns
    (theta of the blocks joined, the blocks' final state, the one-shot trajectory)."""
    chain = rod_chain(2, damping=0.02)
    rng = np.random.default_rng(1)
    ax = 0.5 * rng.standard_normal(500)
    ay = 0.3 * rng.standard_normal(500)
    base = BaseInput(ax, 0.01, ay_mps2=ay if vertical else None)
    one = simulate(chain, 5.0, theta0=(1.0, -0.5), base=base, **kw)
    state, thetas = None, []
    for k0, k1 in splits:
        blk = base.block(k0, k1)
        if state is None:
            tr = simulate(chain, blk.duration_s, theta0=(1.0, -0.5), base=blk, **kw)
            thetas.append(tr.theta_rad)
        else:
            tr = simulate(chain, blk.duration_s, start=state, base=blk, **kw)
            thetas.append(tr.theta_rad[1:])
        state = tr.final_state
    return np.concatenate(thetas), state, one


def assert_blocks_reproduce_one_shot(splits, **kw):
    """:func:`blockwise_and_one_shot`: the blocks' angles joined and their final native state
    equal the one-shot run's bit for bit."""
    joined, state, one = blockwise_and_one_shot(splits, **kw)
    np.testing.assert_array_equal(joined, one.theta_rad)
    np.testing.assert_array_equal(state.native, one.final_state.native)


def random_sturdy_chain(rng, n, mode):
    """Random chains of 0.5-2 kg, 0.3-1.5 m bodies with damping up to 0.5 N m s (no tiny or
    massless bodies: for recursions and couplings checked against dense solves)."""
    m = rng.uniform(0.5, 2.0, n)
    l = rng.uniform(0.3, 1.5, n)
    c = l * rng.uniform(0.1, 0.9, n)
    j = m * l**2 * rng.uniform(0.01, 0.2, n)
    return Chain(m, l, c, j, rng.uniform(0.0, 0.5, n), damping_mode=mode)


def dop853_fixed(chain, base, out_every, y0=None, substeps=2):
    """Fixed-step DOP853 (``substeps`` steps per held sample, no error control) over ``base``
    from ``y0`` (default rest), a row every ``out_every`` samples: the multisample methods'
    reference (within 1e-12 of 4 steps per sample on the paper's drive,
    tests/rig/solvers/test_exponential.py)."""
    from rig.solvers import integrate, solver_named

    y0 = np.zeros(2 * chain.n) if y0 is None else np.array(y0, float)
    return integrate(chain, y0, base.ax_mps2, base.ay_mps2, hold=base.hold, h_in=base.dt_s,
                     n_intervals=base.n_intervals, out_every=out_every,
                     solver=solver_named("dop853", substeps=substeps, adaptive_steps=False)).y_out


def multisample_run(chain, base, method, m, out_every, y0=(0.0, 0.0, 0.0, 0.0)):
    """``method`` (etd3m, etd4m) at ``m`` held samples per step over ``base`` from ``y0``, a row
    every ``out_every`` samples (integrate()'s Run)."""
    from rig.solvers import integrate, solver_named

    return integrate(chain, solver_named(method).init(chain, y0), base.ax_mps2, base.ay_mps2,
                     hold=base.hold, h_in=base.dt_s, n_intervals=base.n_intervals,
                     out_every=out_every, solver=solver_named(method, samples_per_step=m))


def scalar_and_generic_rows(chain, method, m, hold, run_kernel):
    """The n = 2 scalar kernel's rows and integrate()'s (the generic path) for ``method`` at ``m``
    samples per step on 5 s of the paper's drive at 1 kHz with a vertical input (0.3 times the
    horizontal one reversed), from (0.01, -0.02, 0, 0.1), a row every 10 samples.
    ``run_kernel(ax, ay, h, n_intervals, y, y_out)`` runs the scalar kernel in place on ``y``
    and ``y_out``. Returns (integrate's rows, the kernel's rows)."""
    from benchmarks.work_precision import paper_input
    from rig.solvers import integrate, solver_named

    ax = paper_input(5.001).ax_mps2
    ay = 0.3 * ax[::-1].copy()
    n_int, h = 5000, 1e-3
    y0 = np.array([0.01, -0.02, 0.0, 0.1])
    run = integrate(chain, solver_named(method).init(chain, y0), ax, ay, hold=hold, h_in=h,
                    n_intervals=n_int, out_every=10,
                    solver=solver_named(method, samples_per_step=m))
    y = y0.copy()
    y_out = np.empty((n_int // 10 + 1, 4))
    run_kernel(ax, ay, h, n_int, y, y_out)
    return run.y_out, y_out


def swinging_rods():
    """The damped 3-rod chain from (0.3, -0.2, 0.1) rad on 10 s of a linearly interpolated x
    and y input at 200 Hz (a 0.7 Hz sine with seeded noise, a 0.4 Hz cosine): strongly
    nonlinear motion for the generic kernels. Returns (chain, base, y0, fixed-step DOP853's
    angles on it, a row every 20 samples)."""
    chain = rod_chain(3, damping=0.05)
    rng = np.random.default_rng(4)
    t = np.arange(2001) * 5e-3
    ax = 0.5 * np.sin(2 * np.pi * 0.7 * t) + 0.05 * rng.standard_normal(t.size)
    ay = 0.3 * np.cos(2 * np.pi * 0.4 * t)
    base = BaseInput(ax, 5e-3, "linear", ay)
    y0 = (0.3, -0.2, 0.1, 0.0, 0.0, 0.0)
    return chain, base, y0, dop853_fixed(chain, base, out_every=20, y0=y0)[:, :3]
