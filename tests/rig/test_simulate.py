"""simulate(): the held base input, the output grid, validation, block-wise runs, divergence."""

import dataclasses

import numpy as np
import pytest

from rig.chain import Chain
from rig.errors import ConfigError, DivergenceError
from rig.simulate import BaseInput, SimState, Trajectory, simulate

METHOD_KW = {
    "rk4": dict(method="rk4"),
    "dop853": dict(method="dop853", rtol=1e-9),
    "gauss4": dict(method="gauss4"),
    "midpoint": dict(method="midpoint"),
    "linear": dict(method="linear"),
}


@pytest.fixture(scope="module")
def rod():
    """Takeno n = 2: uniform 1 m rods of 1 kg/m, a little joint damping."""
    return Chain((1.0, 1.0), (1.0, 1.0), (0.5, 0.5), (1 / 12, 1 / 12), (0.02, 0.02), "relative")


def random_base(n, dt, hold="zoh", seed=1, vertical=False):
    rng = np.random.default_rng(seed)
    extra = 1 if hold == "linear" else 0
    ay = 0.3 * rng.standard_normal(n + extra) if vertical else None
    return BaseInput(0.5 * rng.standard_normal(n + extra), dt, hold, ay)


# -- BaseInput ----------------------------------------------------------------------------------

def test_base_input_covers_its_intervals_and_is_read_only():
    zoh = BaseInput([1.0, 2.0, 3.0], 0.5)
    lin = BaseInput([1.0, 2.0, 3.0], 0.5, hold="linear")
    assert (zoh.n_intervals, zoh.duration_s) == (3, 1.5)
    assert (lin.n_intervals, lin.duration_s) == (2, 1.0)
    with pytest.raises(ValueError):
        zoh.ax_mps2[0] = 5.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        zoh.dt_s = 1.0
    blk = lin.block(1, 2)
    np.testing.assert_array_equal(blk.ax_mps2, [2.0, 3.0])  # shares its boundary sample


@pytest.mark.parametrize("kwargs, match", [
    (dict(ax_mps2=[0.0, 1.0], dt_s=0.0), r"dt_s = 0\.0 is invalid: expected a finite number > 0"),
    (dict(ax_mps2=[0.0, 1.0], dt_s=float("inf")), r"dt_s = inf is invalid"),
    (dict(ax_mps2=[0.0, 1.0], dt_s=1e-3, hold="cubic"),
     r"hold = 'cubic' is invalid: expected one of zoh, linear"),
    (dict(ax_mps2=[0.0, np.nan, 1.0], dt_s=1e-3), r"ax_mps2\[1\] = nan is invalid: every sample"),
    (dict(ax_mps2=[[0.0, 1.0]], dt_s=1e-3), r"ax_mps2 has shape \(1, 2\)"),
    (dict(ax_mps2=[], dt_s=1e-3), r"ax_mps2 has 0 samples"),
    (dict(ax_mps2=[1.0], dt_s=1e-3, hold="linear"), r"hold = 'linear' needs >= 2"),
    (dict(ax_mps2=[0.0, 1.0], dt_s=1e-3, ay_mps2=[0.0]), r"ay_mps2 has 1 samples; expected 2"),
    (dict(ax_mps2=["a"], dt_s=1e-3), r"ax_mps2 is invalid: expected a 1-D sequence"),
])
def test_bad_base_input_raises_config_error_naming_the_value(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        BaseInput(**kwargs)


# -- output grid and trajectory ------------------------------------------------------------------

def test_default_output_is_every_whole_second_and_the_end(rod):
    base = random_base(2500, 1e-3)
    for kw in (dict(base=base), dict(), dict(method="rk4", dt_s=1e-3)):
        tr = simulate(rod, 2.5, theta0=0.1, estimate_error=False, **kw)
        np.testing.assert_array_equal(tr.t_s, [0.0, 1.0, 2.0, 2.5])
        assert tr.theta_rad.shape == tr.omega_rad_s.shape == (4, 2)
        assert tr.energy_j.shape == (4,)
    tr = simulate(rod, 2.5, theta0=0.1, base=base, output_dt_s=0.01, estimate_error=False)
    np.testing.assert_allclose(tr.t_s, np.arange(251) * 0.01, rtol=0, atol=1e-15)
    assert tr.settings["input_dt_s"] == 1e-3 and tr.settings["hold"] == "zoh"


def test_trajectory_is_frozen_and_describes_itself(rod):
    tr = simulate(rod, 1.0, theta0=(0.3, -0.2), omega0=(0.0, 1.0), method="rk4", dt_s=1e-3)
    assert isinstance(tr, Trajectory) and tr.method == "rk4"
    with pytest.raises(dataclasses.FrozenInstanceError):
        tr.method = "x"
    with pytest.raises(ValueError):
        tr.theta_rad[0, 0] = 1.0
    assert tr.settings["dt_s"] == 1e-3 and tr.settings["order"] == 4
    assert tr.n_steps == 1000 and tr.n_fev == 4000 and tr.wall_time_s > 0
    assert tr.error_estimate_rad.shape == (2, 2) and tr.error_estimate_rad_s.shape == (2, 2)
    np.testing.assert_array_equal(tr.theta_rad[0], [0.3, -0.2])
    np.testing.assert_array_equal(tr.omega_rad_s[0], [0.0, 1.0])
    np.testing.assert_allclose(tr.energy_j, rod.energy(tr.theta_rad, tr.omega_rad_s))
    st = tr.final_state
    assert isinstance(st, SimState) and st.t_s == 1.0 and st.method == "rk4"
    off = simulate(rod, 1.0, theta0=0.3, method="rk4", dt_s=1e-3, estimate_error=False)
    assert off.error_estimate_rad is None and np.isnan(off.max_error_rad)
    assert off.error_method.startswith("not estimated")


# -- validation ---------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    (dict(duration_s=-1.0), r"duration_s = -1\.0 is invalid: expected a finite number > 0"),
    (dict(duration_s=float("nan")), r"duration_s = nan is invalid"),
    (dict(method="euler"), r"method = 'euler' is invalid: expected one of rk4, dop853"),
    (dict(rtol=1.0), r"rtol = 1\.0 is invalid: expected 0 < rtol < 1"),
    (dict(rtol=0.0), r"rtol = 0\.0 is invalid: expected 0 < rtol < 1"),
    (dict(atol=-1e-12), r"atol = -1e-12 is invalid: expected a finite number > 0"),
    (dict(theta0=(0.1, 0.2, 0.3)), r"theta0 has 3 entries; expected 2 \(one per body\)"),
    (dict(theta0=(0.1, np.inf)), r"theta0 = \[0\.1, inf\] is invalid: every entry must be finite"),
    (dict(theta0=None), r"theta0 is missing"),
    (dict(omega0=(1.0,) * 3), r"omega0 has 3 entries; expected 2"),
    (dict(dt_s=1e-3), r"dt_s = 0\.001 is invalid for method 'dop853'"),
    (dict(method="rk4", dt_s=0.0), r"dt_s = 0\.0 is invalid: expected a finite number > 0"),
    (dict(method="rk4", dt_s=0.3), r"dt_s = 0\.3 s is invalid: it must divide duration_s = 2\.0 s"),
    (dict(method="rk4", base="base", dt_s=3e-3),
     r"dt_s = 0\.003 s is invalid: it must divide the input interval base\.dt_s = 0\.01 s"),
    (dict(base="base", duration_s=2.005),
     r"duration_s = 2\.005 s is invalid: expected a whole multiple \(>= 1\) of base\.dt_s"),
    (dict(base="base", duration_s=3.0), r"the base input covers only 2\.0 s"),
    (dict(base="base", output_dt_s=0.015),
     r"output_dt_s = 0\.015 s is invalid: expected a whole multiple \(>= 1\) of base\.dt_s"),
    (dict(base=[0.0, 1.0]), r"base = \[0\.0, 1\.0\] is invalid: expected a BaseInput"),
    (dict(chain="rod"), r"chain = 'rod' is invalid: expected a rig\.chain\.Chain"),
])
def test_bad_arguments_raise_config_error_naming_value_and_valid_range(rod, kwargs, match):
    args = dict(chain=rod, duration_s=2.0, theta0=(0.1, 0.2))
    args.update(kwargs)
    if args.get("base") == "base":
        args["base"] = random_base(200, 0.01)
    chain, duration = args.pop("chain"), args.pop("duration_s")
    with pytest.raises(ConfigError, match=match):
        simulate(chain, duration, **args)


def test_start_and_theta0_are_exclusive(rod):
    tr = simulate(rod, 1.0, theta0=0.1, estimate_error=False)
    with pytest.raises(ConfigError, match="theta0/omega0 and start are both given"):
        simulate(rod, 1.0, theta0=0.1, start=tr.final_state)


# -- block-wise equals one-shot ------------------------------------------------------------------

@pytest.mark.parametrize("hold", ["zoh", "linear"])
@pytest.mark.parametrize("method", list(METHOD_KW))
def test_blockwise_run_reproduces_one_shot_bit_for_bit(rod, method, hold):
    """Three blocks, each started from the previous final_state (native state, carried step
    size), give exactly the one-shot trajectory; a linear-hold block shares its boundary sample."""
    base = random_base(500, 0.01, hold, vertical=True)
    kw = dict(METHOD_KW[method], output_dt_s=0.01, estimate_error=False)
    if method in ("rk4", "gauss4", "midpoint"):
        kw["dt_s"] = 0.005
    one = simulate(rod, 5.0, theta0=(1.0, -0.5), base=base, **kw)
    parts, state = [], None
    for k0, k1 in [(0, 150), (150, 320), (320, 500)]:
        blk = base.block(k0, k1)
        if state is None:
            tr = simulate(rod, blk.duration_s, theta0=(1.0, -0.5), base=blk, **kw)
        else:
            tr = simulate(rod, blk.duration_s, start=state, base=blk, **kw)
        parts.append(tr if state is None else dataclasses.replace(
            tr, t_s=tr.t_s[1:], theta_rad=tr.theta_rad[1:], omega_rad_s=tr.omega_rad_s[1:]))
        state = tr.final_state
    np.testing.assert_array_equal(np.concatenate([p.theta_rad for p in parts]), one.theta_rad)
    np.testing.assert_array_equal(np.concatenate([p.omega_rad_s for p in parts]), one.omega_rad_s)
    np.testing.assert_array_equal(np.concatenate([p.t_s for p in parts]), one.t_s)
    np.testing.assert_array_equal(state.native, one.final_state.native)
    assert state.t_s == one.final_state.t_s == 5.0


def test_same_inputs_give_identical_output(rod):
    base = random_base(300, 0.01, vertical=True)
    a = simulate(rod, 3.0, theta0=(2.0, 2.5), base=base, output_dt_s=0.01)
    b = simulate(rod, 3.0, theta0=(2.0, 2.5), base=base, output_dt_s=0.01)
    for name in ("t_s", "theta_rad", "omega_rad_s", "energy_j", "error_estimate_rad"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert (a.n_steps, a.n_rejected, a.n_fev) == (b.n_steps, b.n_rejected, b.n_fev)


def test_vertical_base_acceleration_acts_like_a_change_of_gravity(rod):
    """A constant y0'' = a is the same as g -> g + a (SPEC section 2)."""
    a = 1.5
    base = BaseInput(np.zeros(300), 0.01, ay_mps2=np.full(300, a))
    heavy = Chain(rod.mass_kg, rod.length_m, rod.com_m, rod.inertia_kgm2, rod.damping_nms,
                  rod.damping_mode, rod.g_mps2 + a)
    kw = dict(theta0=(0.7, -0.4), method="rk4", dt_s=0.005, output_dt_s=0.01,
              estimate_error=False)
    np.testing.assert_allclose(simulate(rod, 3.0, base=base, **kw).theta_rad,
                               simulate(heavy, 3.0, **kw).theta_rad, rtol=0, atol=1e-13)


# -- divergence ---------------------------------------------------------------------------------

def test_unstable_step_raises_divergence_error_with_time_and_last_finite_state(rod):
    """RK4 at dt = 0.5 s on the double rod from large angles blows up; the error carries the
    output instant of the last finite state and that state, which a rerun reproduces."""
    kw = dict(theta0=(2.0, 2.5), method="rk4", dt_s=0.5, estimate_error=False)
    with pytest.raises(DivergenceError, match="non-finite") as info:
        simulate(rod, 60.0, **kw)
    err = info.value
    assert isinstance(err, FloatingPointError)
    assert 0.0 <= err.time_s < 60.0 and err.state.shape == (4,)
    assert np.all(np.isfinite(err.state))
    if err.time_s > 0:
        tr = simulate(rod, err.time_s, **kw)
        np.testing.assert_array_equal(np.concatenate([tr.theta_rad[-1], tr.omega_rad_s[-1]]),
                                      err.state)


def test_gauss_stage_equations_that_cannot_be_solved_raise_divergence_error(rod):
    with pytest.raises(DivergenceError, match="stage equations did not converge") as info:
        simulate(rod, 10.0, theta0=(2.0, 2.5), method="gauss4", dt_s=1.0, estimate_error=False)
    assert info.value.time_s == 0.0
    np.testing.assert_array_equal(info.value.state, [2.0, 2.5, 0.0, 0.0])
