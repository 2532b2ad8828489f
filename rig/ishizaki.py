"""Ishizaki, Fukuda, Nishino & Arai (2009): the double physical pendulum as the n = 2 chain.

Notation of the paper (SPEC sections 2-4) and its map onto :class:`rig.chain.Chain` (bodies 0, 1)::

    r1 = c_1 (O1 to G1),  r2 = c_2 (O2 to G2),  l = l_1 (O1 to O2)
    I1 = J1 + m1 r1^2,  I2 = J2 + m2 r2^2,  D1 = I1 + m2 l^2 (= H_11),  h = m2 l r2 (= H_12)
    S1 = m1 r1 + m2 l,  S2 = m2 r2,  K1 = g S1,  K2 = g S2
    omega1^2 = K1 / D1,  omega2^2 = K2 / I2,  nu = omega2 / omega1,  sigma^2 = r1 omega1^2 / g
    alpha = r2 / r1,  beta^2 = h^2 / (D1 I2),  delta = h / D1,  eps = S1 / (m2 l),  mu = I2 / D1
    zeta1 = Gamma1 / (2 sqrt(D1 K1)),  zeta2 = Gamma2 / (2 sqrt(I2 K2)),  Q = 1 / (2 zeta)

The linearised equations (5)', (6)' with absolute damping are ``H th'' + C th' + g diag(S) th =
-S x0''``. With ``l = r1`` (O2 at G1, the paper's design) and ``xi1 = r1 th1``, ``xi2 = r2 th2``,
their exact solution per unit base acceleration, normalised as the paper's (17), (18),
``H_i = -X_i / (lambda^2 X0) = omega1^2 F[xi_i] / F[x0'']`` with ``lambda = omega / omega1``, is::

    H_i = (-L^2 A_i + i L B_i + C_i) / (L^4 D - i L^3 E - L^2 F + i L G + H),   L = lambda

    A1 = (1-b2)(b2 - s2)                  B1 = -2 zeta2 nu s2 (1-b2)
    C1 = -(1-b2) s2 nu^2
    A2 = (1-b2)(eps b2 - alpha s2 nu^2)   B2 = -2 zeta1 alpha s2 nu^2 (1-b2)
    C2 = -(1-b2) alpha s2 nu^2
    D = (1-b2)^2                          E = (2 zeta1 + 2 zeta2 nu)(1-b2)
    F = (1 + nu^2 + 4 nu zeta1 zeta2)(1-b2)
    G = (2 zeta1 nu^2 + 2 zeta2 nu)(1-b2) H = nu^2 (1-b2)           (b2 = beta^2, s2 = sigma^2)

(derived by Cramer's rule; the paper's printed B1, B2 and G drop two cross-damping terms, SPEC
section 3). The derivation, the printed forms and a physical consequence: docs/ishizaki.md.

The paper compares H1 + H2 (G2, ``x_g2``) with its measured translation; the mirror centre is at O2
= G1, whose translation is xi1 (``x_mirror``, SPEC section 5). |x_g2 / x_mirror| is 1 + alpha
(+0.25 dB) at low frequency, +-10 dB around f2 and within 0.1 dB above 1.5 Hz (fitted preset).

Everything is SI inside (kg, m, kg m^2, N m s/rad, rad/s); frequencies at the interface are in Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from types import MappingProxyType

import numpy as np

from rig.validation import number, positive
from rig.chain import G_STANDARD, Chain
from rig.errors import ConfigError

__all__ = [
    "DesignParameters", "DesignInputs", "PrintedValue", "ClosedFormCoefficients",
    "ClosedFormResponse", "RotationIsolation",
    "design_parameters", "chain_from_design", "coefficients", "closed_form", "closed_form_response",
    "closed_form_modes", "resonances_hz", "antiresonances_hz", "rotation_isolation",
    "table_residuals", "TEXT_DESIGN", "FITTED_DESIGN", "PAPER_TABLE", "PAPER_Q1", "PAPER_Q2",
    "LENGTH2_M",
]

PAPER_Q1 = 530.0  # fitted to the measured curves (section 4), Q = 1/(2 zeta)
PAPER_Q2 = 100.0
#: Default length of body 2 below O2 [m]. The mirror sits at O2 (= G1) and, per section 4, at the
#: centre of the 75 mm tall pendulum, so stage 2 reaches about 75/2 mm below O2. Cosmetic only:
#: nothing hangs below body 2 (mu_2 = 0), so it never enters the dynamics.
LENGTH2_M = 0.0375

_ROUNDOFF = 1e-12  # relative tolerance for "J = 0 up to round-off" and "l = r1"
_UNDAMPED = "> 0 (inf for no damping)"  # what a quality factor may be


# -- design parameters -----------------------------------------------------------------------

@dataclass(frozen=True)
class DesignParameters:
    """The dimensionless and physical design numbers of the paper for one 2-body chain (SI).

    Attributes
    ----------
    alpha : r2 / r1 [-].
    beta2 : beta^2 = (m2 l r2)^2 / ((I1 + m2 l^2) I2) [-], in [0, 1) (1 - beta^2 = det H / (D1 I2)).
    delta : m2 l r2 / (I1 + m2 l^2) [-].
    eps : (m1 r1 + m2 l) / (m2 l) [-] (= 1 + m1/m2 for l = r1).
    mu : I2 / (I1 + m2 l^2) [-].
    nu : omega2 / omega1 [-].
    sigma2 : sigma^2 = r1 omega1^2 / g [-] (= (m1 + m2) r1^2 / (I1 + m2 l^2) for l = r1, so <= 1,
        with equality iff J1 = 0).
    zeta1, zeta2 : damping ratios Gamma1 / (2 sqrt((I1 + m2 l^2)(m1 g r1 + m2 g l))),
        Gamma2 / (2 sqrt(I2 m2 g r2)) [-].
    omega1, omega2 : sqrt((m1 g r1 + m2 g l) / (I1 + m2 l^2)), sqrt(m2 g r2 / I2) [rad/s].
    f1_hz, f2_hz : omega1 / 2 pi, omega2 / 2 pi [Hz].
    r1, r2, l : O1G1, O2G2, O1O2 [m].
    Q1, Q2 : 1 / (2 zeta1), 1 / (2 zeta2) [-] (``inf`` without damping).
    g_mps2 : gravitational acceleration [m/s^2].

    Construction checks finiteness and the ranges above (ConfigError names the field); it does not
    check that the numbers are mutually consistent, so a hand-made design (e.g. with sigma2 = 1)
    can be evaluated by the closed forms.
    """

    alpha: float
    beta2: float
    delta: float
    eps: float
    mu: float
    nu: float
    sigma2: float
    zeta1: float
    zeta2: float
    omega1: float
    omega2: float
    f1_hz: float
    f2_hz: float
    r1: float
    r2: float
    l: float
    Q1: float
    Q2: float
    g_mps2: float = G_STANDARD

    def __post_init__(self):
        for f in fields(self):
            where, v = f"DesignParameters.{f.name}", getattr(self, f.name)
            if f.name in ("Q1", "Q2"):
                v = positive(where, v, allow_inf=True, valid=_UNDAMPED)
            elif f.name in ("zeta1", "zeta2"):
                v = number(where, v, lo=0.0)
            elif f.name == "beta2":
                v = number(where, v, lo=0.0, hi=1.0, hi_open=True,
                           valid="0 <= beta^2 < 1 (a positive definite mass matrix)")
            else:
                v = positive(where, v)
            object.__setattr__(self, f.name, v)


def design_parameters(chain: Chain) -> DesignParameters:
    """The paper's design numbers of a 2-body chain with absolute damping.

    Parameters
    ----------
    chain : a :class:`Chain` with ``n == 2``, ``damping_mode == "absolute"`` and ``com_m[0] > 0``
        (r1 = c_1, r2 = c_2, l = l_1; ``length_m[1]`` does not enter).

    Returns
    -------
    DesignParameters
        See its attributes for the definitions (SPEC section 2, Ishizaki (7)', (8)', (15), (16)).

    Raises
    ------
    ConfigError
        If the chain is not a 2-body chain with absolute damping (the paper's zeta are defined for
        a torque ``-Gamma_j th_j'``), or r1 = com_m[0] <= 0 (alpha, sigma^2 need r1 > 0).
    """
    if not isinstance(chain, Chain):
        raise ConfigError(f"chain = {chain!r} is invalid: expected a rig.chain.Chain")
    if chain.n != 2:
        raise ConfigError(
            f"chain has n = {chain.n} bodies; Ishizaki's design parameters need n = 2")
    if chain.damping_mode != "absolute":
        raise ConfigError(f"chain.damping_mode = {chain.damping_mode!r}; Ishizaki's zeta1, zeta2 "
                          "are defined for absolute damping (torque -Gamma_j th_j', "
                          "eqs. (5)', (6)')")
    m1, m2 = chain.mass_kg
    r1, r2 = chain.com_m
    j1, j2 = chain.inertia_kgm2
    l = chain.length_m[0]
    gam1, gam2 = chain.damping_nms
    g = chain.g_mps2
    if not r1 > 0:
        raise ConfigError(f"chain.com_m[0] = r1 = {r1}; Ishizaki's parameters need r1 > 0 "
                          "(alpha = r2/r1, sigma^2 = r1 omega1^2/g)")
    i2 = j2 + m2 * r2**2
    d1 = j1 + m1 * r1**2 + m2 * l**2
    s1 = m1 * r1 + m2 * l
    h = m2 * l * r2
    k1, k2 = g * s1, g * m2 * r2
    w1, w2 = math.sqrt(k1 / d1), math.sqrt(k2 / i2)
    z1 = gam1 / (2 * math.sqrt(d1 * k1))
    z2 = gam2 / (2 * math.sqrt(i2 * k2))
    return DesignParameters(
        alpha=r2 / r1, beta2=h * h / (d1 * i2), delta=h / d1, eps=s1 / (m2 * l), mu=i2 / d1,
        nu=w2 / w1, sigma2=r1 * w1**2 / g, zeta1=z1, zeta2=z2, omega1=w1, omega2=w2,
        f1_hz=w1 / (2 * math.pi), f2_hz=w2 / (2 * math.pi), r1=r1, r2=r2, l=l,
        Q1=math.inf if z1 == 0 else 1 / (2 * z1), Q2=math.inf if z2 == 0 else 1 / (2 * z2),
        g_mps2=g)


# -- design numbers -> chain -----------------------------------------------------------------

def chain_from_design(*, r1_m, r2_m, f1_hz, f2_hz, eps, total_mass_kg, q1, q2, l_m=None,
                      length2_m=LENGTH2_M, g_mps2=G_STANDARD) -> Chain:
    """Build the 2-body chain with the given design numbers (SPEC section 4).

    The derivation inverts the definitions of :class:`DesignParameters` (M = total mass,
    omega_i = 2 pi f_i)::

        eps = 1 + m1 r1 / (m2 l)         ->  m2 = M / (1 + (eps - 1) l / r1),  m1 = M - m2
        omega1^2 = g S1 / (J1 + m1 r1^2 + m2 l^2)
                                         ->  J1 = m1 r1 (g/omega1^2 - r1) + m2 l (g/omega1^2 - l)
        omega2^2 = g m2 r2 / (J2 + m2 r2^2)  ->  J2 = m2 r2 (g/omega2^2 - r2)
        Q1 = 1/(2 zeta1)  ->  Gamma1 = sqrt(D1 K1) / Q1 = g S1 / (omega1 Q1)
        Q2 = 1/(2 zeta2)  ->  Gamma2 = sqrt(I2 K2) / Q2 = g m2 r2 / (omega2 Q2)

    With l = r1 the response depends only on r1, r2, f1, f2, eps and g; M scales masses, inertias
    and dampings together.

    Parameters
    ----------
    r1_m, r2_m : O1 to G1, O2 to G2 [m], > 0.
    f1_hz, f2_hz : omega1 / 2 pi, omega2 / 2 pi [Hz], > 0 (stage 1 with stage 2 locked to it as a
        point mass at O2, stage 2 alone about O2; not the coupled modes).
    eps : (m1 r1 + m2 l) / (m2 l) [-], > 1 (m1 > 0).
    total_mass_kg : m1 + m2 [kg], > 0.
    q1, q2 : quality factors 1/(2 zeta1), 1/(2 zeta2) [-], > 0; ``math.inf`` for no damping.
    l_m : O1 to O2 [m]; ``None`` (default) puts O2 at G1 (l = r1), the paper's design.
    length2_m : length of body 2 below O2 [m] (places its lower end only; no dynamical effect).
    g_mps2 : gravitational acceleration [m/s^2].

    Returns
    -------
    Chain
        Absolute damping, bodies (stage 1, stage 2).

    Raises
    ------
    ConfigError
        For non-positive or non-finite inputs, eps <= 1, or a design that needs J1 < 0 (r1 too
        long for f1: with l = r1 this is r1 > g/omega1^2, i.e. sigma^2 > 1) or J2 < 0
        (r2 > g/omega2^2). The bound is J >= 0; a value within 1e-12 of the body's pivot inertia is
        taken as round-off and set to 0.
    """
    r1 = positive("r1_m", r1_m)
    r2 = positive("r2_m", r2_m)
    f1 = positive("f1_hz", f1_hz)
    f2 = positive("f2_hz", f2_hz)
    mtot = positive("total_mass_kg", total_mass_kg)
    q1 = positive("q1", q1, allow_inf=True, valid=_UNDAMPED)
    q2 = positive("q2", q2, allow_inf=True, valid=_UNDAMPED)
    l = r1 if l_m is None else positive("l_m", l_m)
    length2 = positive("length2_m", length2_m)
    g = positive("g_mps2", g_mps2)
    eps = number("eps", eps, lo=1.0, lo_open=True,
                 valid="a finite number > 1 (eps = 1 + m1 r1/(m2 l) and m1 > 0)")
    m2 = mtot / (1 + (eps - 1) * l / r1)
    m1 = mtot - m2
    w1, w2 = 2 * math.pi * f1, 2 * math.pi * f2
    leq1, leq2 = g / w1**2, g / w2**2  # equivalent simple-pendulum lengths [m]
    j1 = m1 * r1 * (leq1 - r1) + m2 * l * (leq1 - l)
    j2 = m2 * r2 * (leq2 - r2)
    for name, j, scale, detail in (
            ("J1", j1, m1 * r1**2 + m2 * l**2,
             f"r1_m = {r1}, l_m = {l}, f1_hz = {f1}, eps = {eps}: J1 = m1 r1 (g/omega1^2 - r1) + "
             f"m2 l (g/omega1^2 - l) with g/omega1^2 = {leq1:.6g} m"),
            ("J2", j2, m2 * r2**2,
             f"r2_m = {r2}, f2_hz = {f2}: J2 = m2 r2 (g/omega2^2 - r2) with g/omega2^2 = "
             f"{leq2:.6g} m")):
        if j < 0:
            if j >= -_ROUNDOFF * scale:
                continue
            raise ConfigError(f"the design needs {name} = {j:.6g} kg m^2 ({detail}); a rigid body "
                              f"needs {name} >= 0: the pivot-to-centre distance is longer than the "
                              "equivalent simple pendulum of that frequency")
    j1, j2 = max(j1, 0.0), max(j2, 0.0)
    s1 = m1 * r1 + m2 * l
    gam1 = 0.0 if math.isinf(q1) else g * s1 / (w1 * q1)
    gam2 = 0.0 if math.isinf(q2) else g * m2 * r2 / (w2 * q2)
    return Chain(mass_kg=(m1, m2), length_m=(l, length2), com_m=(r1, r2), inertia_kgm2=(j1, j2),
                 damping_nms=(gam1, gam2), damping_mode="absolute", g_mps2=g)


@dataclass(frozen=True)
class DesignInputs:
    """A set of inputs of :func:`chain_from_design` (same names and units).

    ``chain_from_design(**dataclasses.asdict(inputs))`` or ``inputs.chain()`` builds it.
    """

    r1_m: float
    r2_m: float
    f1_hz: float
    f2_hz: float
    eps: float
    total_mass_kg: float
    q1: float = PAPER_Q1
    q2: float = PAPER_Q2
    l_m: float | None = None
    length2_m: float = LENGTH2_M
    g_mps2: float = G_STANDARD

    def chain(self) -> Chain:
        """The chain of these inputs (see :func:`chain_from_design`)."""
        return chain_from_design(**{f.name: getattr(self, f.name) for f in fields(self)})


#: The numbers of the paper's text: r1 = 29 mm, r2 = 0.85 mm, f1 = 2.48 Hz, f2 = 0.83 Hz,
#: eps = 2.13, about 100 g, Q1 = 530, Q2 = 100. Rounded; it misses beta^2, nu, sigma^2 and alpha
#: of the table by more than their last printed digit (see :func:`table_residuals`).
TEXT_DESIGN = DesignInputs(r1_m=0.029, r2_m=0.00085, f1_hz=2.48, f2_hz=0.83, eps=2.13,
                           total_mass_kg=0.100)
#: A least-squares fit to every number printed in the design table except mu (SPEC section 4); it
#: reproduces each of them within half a unit of its last printed digit.
FITTED_DESIGN = DesignInputs(r1_m=0.02899, r2_m=0.000846, f1_hz=2.4783, f2_hz=0.8268, eps=2.1338,
                             total_mass_kg=0.100)


@dataclass(frozen=True)
class PrintedValue:
    """A number as printed in the paper: ``value`` (SI) given to ``digits`` significant digits."""

    value: float
    digits: int
    unit: str = "-"

    @property
    def half_unit(self) -> float:
        """Half a unit of the last printed digit (in the unit of ``value``)."""
        return 0.5 * 10.0 ** (math.floor(math.log10(abs(self.value))) - self.digits + 1)


#: The design table of section 3 (keys are :class:`DesignParameters` attribute names; SI).
#: mu = 9.18e-2 is inconsistent with the rest, which imply mu = alpha / (eps nu^2) ~ 0.123.
PAPER_TABLE = MappingProxyType({
    "alpha": PrintedValue(2.92e-2, 3),
    "beta2": PrintedValue(7.82e-4, 3),
    "eps": PrintedValue(2.13, 3),
    "mu": PrintedValue(9.18e-2, 3),
    "nu": PrintedValue(0.334, 3),
    "sigma2": PrintedValue(0.717, 3),
    "r1": PrintedValue(0.029, 2, "m"),
    "r2": PrintedValue(0.00085, 2, "m"),
    "f1_hz": PrintedValue(2.48, 3, "Hz"),
    "f2_hz": PrintedValue(0.83, 2, "Hz"),
})


def table_residuals(design: DesignParameters) -> dict[str, float]:
    """(computed - printed) / half a unit of the last printed digit, per :data:`PAPER_TABLE` entry.

    ``abs(r) <= 1`` means the entry is reproduced to its printed precision.
    """
    return {k: (getattr(design, k) - p.value) / p.half_unit for k, p in PAPER_TABLE.items()}


# -- closed forms (17), (18) -----------------------------------------------------------------

@dataclass(frozen=True)
class ClosedFormCoefficients:
    """Coefficients of (17), (18): H_i = (-l^2 A_i + i l B_i + C_i) / (l^4 D - i l^3 E - l^2 F +
    i l G + H), l = lambda = omega / omega1 (all dimensionless)."""

    A1: float
    B1: float
    C1: float
    A2: float
    B2: float
    C2: float
    D: float
    E: float
    F: float
    G: float
    H: float


def _require_l_equals_r1(design: DesignParameters, what: str) -> None:
    if abs(design.l - design.r1) > _ROUNDOFF * design.r1:
        raise ConfigError(f"{what} assumes l = r1 (O2 at G1, Ishizaki section 2); got l = "
                          f"{design.l} m, r1 = {design.r1} m. Use Chain.frf_angles for l != r1")


def coefficients(design: DesignParameters, *, printed: bool = False) -> ClosedFormCoefficients:
    """The coefficients A_i ... H of (17), (18).

    Parameters
    ----------
    design : design numbers with l = r1.
    printed : ``False`` (default): exact for the linear model (5)', (6)' (B1, B2, G corrected, see
        the module docstring). ``True``: as printed in the paper, B1 = 2 zeta2 nu (beta^2 -
        sigma^2), B2 = 2 zeta1 (eps beta^2 - alpha sigma^2 nu^2), G = 2 zeta1 nu^2 + 2 zeta2 nu.
    """
    _require_l_equals_r1(design, "Ishizaki's closed forms (17), (18)")
    a, b2, e, s2, nu = design.alpha, design.beta2, design.eps, design.sigma2, design.nu
    z1, z2 = design.zeta1, design.zeta2
    ob = 1.0 - b2
    if printed:
        bb1 = 2 * z2 * nu * (b2 - s2)
        bb2 = 2 * z1 * (e * b2 - a * s2 * nu**2)
        gg = 2 * z1 * nu**2 + 2 * z2 * nu
    else:
        bb1 = -2 * z2 * nu * s2 * ob
        bb2 = -2 * z1 * a * s2 * nu**2 * ob
        gg = (2 * z1 * nu**2 + 2 * z2 * nu) * ob
    return ClosedFormCoefficients(
        A1=ob * (b2 - s2), B1=bb1, C1=-ob * s2 * nu**2,
        A2=ob * (e * b2 - a * s2 * nu**2), B2=bb2, C2=-ob * a * s2 * nu**2,
        D=ob**2, E=(2 * z1 + 2 * z2 * nu) * ob, F=(1 + nu**2 + 4 * nu * z1 * z2) * ob, G=gg,
        H=nu**2 * ob)


def closed_form(design: DesignParameters, freqs_hz, *, printed: bool = False):
    """Ishizaki's (17), (18): H1, H2 (dimensionless) at ``freqs_hz`` [Hz].

    ``H_i = -X_i / (lambda^2 X0) = omega1^2 F[xi_i] / F[x0'']`` with xi1 = x1 - x0 = r1 th1 and
    xi2 = x2 - x1 = r2 th2 (l = r1); H1 -> -sigma^2, H2 -> -alpha sigma^2 as f -> 0.

    Parameters
    ----------
    design : design numbers with l = r1 (ConfigError otherwise).
    freqs_hz : frequencies [Hz], any shape.
    printed : use the paper's printed B1, B2, G instead of the corrected ones (see
        :func:`coefficients`).

    Returns
    -------
    (H1, H2) : complex arrays of the shape of ``freqs_hz``.
    """
    c = coefficients(design, printed=printed)
    lam = 2 * np.pi * np.asarray(freqs_hz, float) / design.omega1
    il = 1j * lam
    l2 = lam * lam
    den = l2 * l2 * c.D - il * l2 * c.E - l2 * c.F + il * c.G + c.H
    h1 = (-l2 * c.A1 + il * c.B1 + c.C1) / den
    h2 = (-l2 * c.A2 + il * c.B2 + c.C2) / den
    return h1, h2


@dataclass(frozen=True, eq=False)
class ClosedFormResponse:
    """(17), (18) on a frequency grid, with their physical-unit views (per unit base acceleration).

    Attributes
    ----------
    freqs_hz : frequencies [Hz].
    h1, h2 : the paper's normalised H1, H2 [-].
    omega1 : [rad/s]; r1, r2 : [m].
    """

    freqs_hz: np.ndarray
    h1: np.ndarray
    h2: np.ndarray
    omega1: float
    r1: float
    r2: float

    @property
    def xi1(self) -> np.ndarray:
        """x1 - x0 = r1 th1 = H1 / omega1^2: G1 relative to the base [m per m/s^2]. With l = r1 this
        is also O2, the mirror centre (SPEC section 5's translation channel). -> -r1/g at 0 Hz."""
        return self.h1 / self.omega1**2

    @property
    def xi2(self) -> np.ndarray:
        """x2 - x1 = r2 th2 = H2 / omega1^2 [m per m/s^2]."""
        return self.h2 / self.omega1**2

    @property
    def x_g2(self) -> np.ndarray:
        """x2 - x0 = (H1 + H2) / omega1^2: G2 relative to the base [m per m/s^2], what the paper
        plots against its measured translation."""
        return (self.h1 + self.h2) / self.omega1**2

    @property
    def x_mirror(self) -> np.ndarray:
        """The mirror centre O2 (= G1) relative to the base, l th1 = xi1 [m per m/s^2]."""
        return self.xi1

    @property
    def theta1(self) -> np.ndarray:
        """Theta_1 = xi1 / r1 [rad per m/s^2]; -> -1/g at 0 Hz."""
        return self.xi1 / self.r1

    @property
    def theta2(self) -> np.ndarray:
        """Theta_2 = xi2 / r2 [rad per m/s^2], the rotation channel; -> -1/g at 0 Hz."""
        return self.xi2 / self.r2


def closed_form_response(design: DesignParameters, freqs_hz, *,
                         printed: bool = False) -> ClosedFormResponse:
    """:func:`closed_form` packed with the numbers that turn it into physical units."""
    f = np.asarray(freqs_hz, float)
    h1, h2 = closed_form(design, f, printed=printed)
    return ClosedFormResponse(freqs_hz=f, h1=h1, h2=h2, omega1=design.omega1, r1=design.r1,
                              r2=design.r2)


def closed_form_modes(design: DesignParameters, *, printed: bool = False):
    """Damped modes from the roots of the denominator of (17), (18).

    With s = i lambda the denominator is the real polynomial D s^4 + E s^3 + F s^2 + G s + H.

    Returns
    -------
    (freqs_hz, q) : natural frequencies |s| omega1 / 2 pi [Hz] and quality factors
        |s| / (-2 Re s) of the oscillatory pole pairs, ascending in frequency.
    """
    c = coefficients(design, printed=printed)
    s = np.roots([c.D, c.E, c.F, c.G, c.H])
    s = s[s.imag > 0]
    order = np.argsort(np.abs(s))
    s = s[order]
    with np.errstate(divide="ignore"):
        q = np.abs(s) / (-2 * s.real)
    return np.abs(s) * design.omega1 / (2 * np.pi), q


# -- resonances, anti-resonances, rotation isolation -----------------------------------------

def resonances_hz(design: DesignParameters, *, stable: bool = True) -> np.ndarray:
    """Undamped resonances (19): lambda^2 roots of (1 - b2) lambda^4 - (1 + nu^2) lambda^2 + nu^2.

    ``lambda_-+^2 = ((1 + nu^2) -+ sqrt((1 - nu^2)^2 + 4 beta^2 nu^2)) / (2 (1 - beta^2))``.

    Parameters
    ----------
    design : design numbers (any l: (19) comes from the mass and stiffness matrices alone).
    stable : ``True`` (default) takes lambda_-^2 = 2 nu^2 / ((1 + nu^2) + sqrt(...)) (Vieta), which
        avoids the cancellation of the literal (19) as beta^2 -> 1; ``False`` evaluates (19)
        literally.

    Returns
    -------
    (2,) array [Hz]: (f_-, f_+) = lambda_-+ omega1 / 2 pi.
    """
    b2, nu = design.beta2, design.nu
    p = 1 + nu**2
    root = math.sqrt((1 - nu**2) ** 2 + 4 * b2 * nu**2)
    lp2 = (p + root) / (2 * (1 - b2))
    lm2 = 2 * nu**2 / (p + root) if stable else (p - root) / (2 * (1 - b2))
    return np.sqrt([lm2, lp2]) * design.omega1 / (2 * np.pi)


def antiresonances_hz(design: DesignParameters) -> np.ndarray:
    """Undamped anti-resonances (20) of H1 (and Theta_1) and (21) of H2 (and Theta_2) [Hz].

    ``lambda_z1 = nu (1 - beta^2/sigma^2)^(-1/2)`` (20), ``lambda_z2 = (1 - eps beta^2 / (alpha
    sigma^2 nu^2))^(-1/2)`` (21), i.e. the zeros of the undamped numerators -lambda^2 A_i + C_i.
    A zero moved to infinity (A_i = 0 to round-off, i.e. its two terms agree to 8 ulp; for (21)
    that is design goal (ii), sigma^2 = 1) is ``inf``; no positive real root (beta^2 > sigma^2,
    resp. eps beta^2 > alpha sigma^2 nu^2) is ``nan``. Needs l = r1.

    Returns
    -------
    (2,) array [Hz]: (f_z1, f_z2).
    """
    _require_l_equals_r1(design, "the anti-resonances (20), (21)")
    a, b2, e, s2, nu = design.alpha, design.beta2, design.eps, design.sigma2, design.nu
    # numerator zeros: coef lambda^2 + q = 0 with coef = b2 - s2, q = s2 nu^2 for (20) and
    # coef = eps b2 - alpha s2 nu^2, q = alpha s2 nu^2 for (21) (A_i / (1-b2) and -C_i / (1-b2))
    out = []
    for x, y, q in ((b2, s2, s2 * nu**2), (e * b2, a * s2 * nu**2, a * s2 * nu**2)):
        coef = x - y
        if abs(coef) <= 8 * np.finfo(float).eps * max(x, y):  # zero up to round-off: at infinity
            out.append(math.inf)
            continue
        lam2 = -q / coef
        out.append(math.sqrt(lam2) * design.omega1 / (2 * math.pi) if lam2 > 0 else math.nan)
    return np.asarray(out)


@dataclass(frozen=True)
class RotationIsolation:
    """Exact high-frequency limit of theta2/theta1, next to claim (29) |theta2/theta1| = alpha.

    Attributes
    ----------
    ratio : exact limit nu^2 (1 - sigma^2) / (1 - beta^2/sigma^2) = A2 / (alpha A1) [-] (signed;
        positive = in phase).
    ratio_db : 20 log10 |ratio| [dB].
    alpha : r2 / r1 [-].
    alpha_db : 20 log10 alpha [dB].
    """

    ratio: float
    ratio_db: float
    alpha: float
    alpha_db: float


def rotation_isolation(design: DesignParameters) -> RotationIsolation:
    """The exact limit of theta2/theta1 for omega >> omega1, next to alpha (claim (29)).

    As lambda -> infinity, H2/H1 -> A2/A1 and theta2/theta1 = (H2/r2)/(H1/r1) -> A2 / (alpha A1)
    = (eps beta^2 - alpha sigma^2 nu^2) / (alpha (beta^2 - sigma^2)), which for l = r1 (where
    eps beta^2 = alpha sigma^4 nu^2) is nu^2 (1 - sigma^2) / (1 - beta^2/sigma^2). It is 0 for
    design goal (ii) (sigma^2 = 1): then |theta2/theta1| falls as lambda^-2 instead.
    """
    _require_l_equals_r1(design, "the rotation-isolation limit")
    s2, b2, nu = design.sigma2, design.beta2, design.nu
    ratio = nu**2 * (1 - s2) / (1 - b2 / s2)
    with np.errstate(divide="ignore"):
        ratio_db = float(20 * np.log10(abs(ratio)))
    return RotationIsolation(ratio=ratio, ratio_db=ratio_db, alpha=design.alpha,
                             alpha_db=20 * math.log10(design.alpha))
