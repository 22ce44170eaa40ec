"""MR damper forward models and the linear passive damper (docs/model.md, section 4).

Every model shares one interface: ``(stroke x, stroke rate v, current i, internal state) ->
(force F, state derivative)``. Sign convention (docs/model.md 1): ``x = z_c - z_b``, ``F > 0`` resists
``v > 0``; the force acts as ``-F`` on the car body and ``+F`` on the bogie.

Each model is a frozen dataclass of parameters that packs into a fixed-length float vector
(:meth:`as_array`) read by the compiled kernels, so a batch of parameter sets (one row per
vehicle) gives domain randomisation for free. The internal state is ``[z, y]``: the Bouc-Wen
hysteretic variable ``z`` (m) and Spencer's internal displacement ``y`` (m); models without them
ignore them. The coil current the model sees is the *actual* current; the coil/driver lag
``i' = (i_cmd - i) / tau`` is integrated by the plant (``coil_time_constant_s``, 0 = none).

| model | name | provenance of the default values |
| --- | --- | --- |
| :class:`LinearDamper` | ``"passive"`` | c_s of docs/model.md 2 [reconstructed] |
| :class:`ReferenceDamper` | ``"reference"`` | Spencer et al. 1997 x 5 in force [standard, scaled] |
| :class:`BoucWenDamper` | ``"bouc_wen"`` | identified from reference loops (docs/model.md 6) |
| :class:`TanhDamper` | ``"tanh"`` | identified from reference loops (docs/model.md 6) |
| :class:`BiExponentialDamper` | ``"bi_exponential"`` | identified from reference loops (docs/model.md 6) |
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
from numba import njit

from capsule_env._fastmath import BORROWED, FAST, fast_exp, fast_tanh_nonneg
from capsule_env._validation import (
    check_array_in_range,
    check_choice,
    check_finite,
    check_nonnegative,
    check_positive,
)
from capsule_env.hysteresis import hysteresis_rate
from capsule_env.layout import (
    BRANCH_BLEND,
    BW_A,
    BW_ALPHA_A,
    BW_ALPHA_B,
    BW_BETA,
    BW_C0A,
    BW_C0B,
    BW_GAMMA,
    BW_K0,
    BW_X0,
    BX_A0,
    BX_A1,
    BX_B0,
    BX_B1,
    BX_C0,
    BX_C1,
    BX_D,
    BX_LOWER,
    BX_UPPER,
    COIL_TAU,
    DAMPER_PARAM_NAMES,
    I_MAX,
    N_DAMPER_PARAMS,
    PV_DAMPING,
    SP_A,
    SP_ALPHA_A,
    SP_ALPHA_B,
    SP_BETA,
    SP_C0A,
    SP_C0B,
    SP_C1A,
    SP_C1B,
    SP_GAMMA,
    SP_K0,
    SP_K1,
    SP_X0,
    TH_ALPHA_A,
    TH_ALPHA_B,
    TH_BETA,
    TH_C_A,
    TH_C_B,
    TH_DELTA,
    TH_F0_A,
    TH_F0_B,
    TH_K_A,
    TH_K_B,
)

__all__ = [
    "PASSIVE",
    "REFERENCE",
    "BOUC_WEN",
    "TANH",
    "BI_EXPONENTIAL",
    "DAMPER_NAMES",
    "N_DAMPER_PARAMS",
    "LinearDamper",
    "ReferenceDamper",
    "BoucWenDamper",
    "TanhDamper",
    "BiExponentialDamper",
    "DamperParams",
    "make_damper",
    "damper_force",
]

# Integer codes used by the compiled kernels.
PASSIVE, REFERENCE, BOUC_WEN, TANH, BI_EXPONENTIAL = 0, 1, 2, 3, 4
DAMPER_NAMES = ("passive", "reference", "bouc_wen", "tanh", "bi_exponential")


class _DamperBase:
    """Shared packing/validation for the damper dataclasses."""

    code: ClassVar[int]
    name: ClassVar[str]

    def as_array(self) -> np.ndarray:
        """Packed float64 vector of length :data:`N_DAMPER_PARAMS` for the kernels: the
        model's parameters in the order of ``layout.DAMPER_PARAM_NAMES[name]``, then
        ``max_current_a``, ``coil_time_constant_s`` and ``branch_blend_m`` (0 where absent)."""
        out = np.zeros(N_DAMPER_PARAMS)
        for slot, field_name in enumerate(DAMPER_PARAM_NAMES[self.name]):
            out[slot] = getattr(self, field_name)
        out[I_MAX] = getattr(self, "max_current_a", 0.0)
        out[COIL_TAU] = getattr(self, "coil_time_constant_s", 0.0)
        out[BRANCH_BLEND] = getattr(self, "branch_blend_m", 0.0)
        return out

    def _validate_common(self) -> None:
        for f in fields(self):  # type: ignore[arg-type]
            check_finite(f.name, getattr(self, f.name))
        if hasattr(self, "max_current_a"):
            check_positive("max_current_a", self.max_current_a)
            check_nonnegative("coil_time_constant_s", self.coil_time_constant_s)


@dataclass(frozen=True)
class LinearDamper(_DamperBase):
    """Linear viscous passive damper ``F = c v`` (the passive baseline, docs/model.md 2/7).

    ``damping_n_s_per_m``: c_s (N s/m), default 1.5e4 [reconstructed].
    """

    damping_n_s_per_m: float = 1.5e4
    code: ClassVar[int] = PASSIVE
    name: ClassVar[str] = "passive"

    def __post_init__(self) -> None:
        self._validate_common()
        check_nonnegative("damping_n_s_per_m", self.damping_n_s_per_m)


@dataclass(frozen=True)
class ReferenceDamper(_DamperBase):
    """Spencer et al. (1997) modified Bouc-Wen model: the "hardware" in simulation (docs/model.md 4.2).

    ::

        F  = c1 y' + k1 (x - x0)
        y' = (alpha z + c0 x' + k0 (x - y)) / (c0 + c1)
        z' = -gamma |x' - y'| z |z| - beta (x' - y') z^2 + A (x' - y')      (n = 2)
        p(i) = p_a + p_b i   for alpha, c0, c1;   i' = (i_cmd - i) / tau

    Provenance: [standard form, scaled]. Spencer's published values in SI with every force
    coefficient x 5 (capsule size) and command voltage replaced by current through
    ``u = 1.5 V/A * i`` (b-coefficients = Spencer's per-volt values x 5 x 1.5). Spencer's
    eta = 190 1/s becomes ``coil_time_constant_s = 1/190``. ``n`` is fixed at Spencer's 2, which
    gives the closed-form hysteresis update used by the integrator.
    """

    c0a: float = 1.05e4
    c0b: float = 2.625e3
    c1a: float = 1.415e5
    c1b: float = 2.2125e3
    alpha_a: float = 7.0e4
    alpha_b: float = 5.2125e5
    k0: float = 2.345e4
    k1: float = 2.5e3
    x0: float = 0.0
    gamma: float = 3.63e6
    beta: float = 3.63e6
    a_coef: float = 301.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 1.0 / 190.0
    code: ClassVar[int] = REFERENCE
    name: ClassVar[str] = "reference"

    def __post_init__(self) -> None:
        self._validate_common()
        for n in ("c0a", "c1a", "a_coef"):
            check_positive(n, getattr(self, n))
        for n in ("c0b", "c1b", "alpha_a", "alpha_b", "k0", "k1"):
            check_nonnegative(n, getattr(self, n))
        _check_bouc_wen_shape(self.gamma, self.beta)


@dataclass(frozen=True)
class BoucWenDamper(_DamperBase):
    """Bouc-Wen MR damper model (paper eq. 1, docs/model.md 4.3) [standard form]::

        F  = c0 x' + k0 (x - x0) + alpha z
        z' = -gamma |x'| z |z| - beta x' z^2 + A x'        (n = 2)
        alpha = alpha_a + alpha_b i,   c0 = c0a + c0b i

    Default values: identified from the reference damper's loops (1 Hz, +-25 mm, 0-1.5 A) by
    nonlinear least squares in the A = 1 form (z in metres, yield displacement
    ``1/sqrt(gamma + beta)``): ``python -m capsule_env.identify --emit-defaults`` regenerates
    them and ``tests/test_identification.py`` checks they agree. ``n`` is fixed at 2
    (closed-form hysteresis update).
    """

    c0a: float = 8432.5
    c0b: float = 11518.0
    alpha_a: float = 8.8191e7
    alpha_b: float = 2.6567e8
    k0: float = 15768.0
    x0: float = 0.00038801
    gamma: float = 2.0282e10
    beta: float = 1.0146e7
    a_coef: float = 1.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    code: ClassVar[int] = BOUC_WEN
    name: ClassVar[str] = "bouc_wen"

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("a_coef", self.a_coef)
        _check_bouc_wen_shape(self.gamma, self.beta)


@dataclass(frozen=True)
class TanhDamper(_DamperBase):
    """Hyperbolic-tangent hysteresis model (paper eq. 3, Kwok et al. 2006, docs/model.md 4.4)::

        F = c v + k x + alpha tanh(beta v + delta sgn_w(x)) + f0
        c, k, alpha, f0 linear in current (p = p_a + p_b i); beta, delta constant

    ``sgn_w`` is ``sign(x)`` made continuous over ``|x| < branch_blend_m`` (see
    :func:`branch_weight`): the literal sign makes the force jump at x = 0, where a vehicle at
    rest starts, and no fixed-step integrator converges there.

    Default values: identified from the reference damper's loops (variable projection over
    beta, delta; ``python -m capsule_env.identify --emit-defaults``).
    """

    c_a: float = 7712.4
    c_b: float = 3348.4
    k_a: float = 22663.0
    k_b: float = -4151.8
    alpha_a: float = 715.17
    alpha_b: float = 2902.5
    f0_a: float = -8.1468
    f0_b: float = 2.7051
    beta: float = 40.729
    delta: float = -0.072137
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    branch_blend_m: float = 1e-4
    code: ClassVar[int] = TANH
    name: ClassVar[str] = "tanh"

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("beta", self.beta)
        _check_blend(self.branch_blend_m)


@dataclass(frozen=True)
class BiExponentialDamper(_DamperBase):
    """Bi-exponential MR damper model (paper eq. 4, docs/model.md 4.5) [reconstructed form]::

        S_d(v) = sign(v) (1 - exp(-d |v|))
        F(v, i) = a(i) S_d(v) + b(i) v + c(i)    (upper set when x >= 0, lower set when x < 0)
        a(i) = a0 + a1 i,  b(i) = b0 + b1 i,  c(i) = c0 + c1 i,  d constant per branch (s/m)

    a: yield force (N), b: post-yield viscous slope (N s/m), c: hysteresis offset (N).
    Within ``|x| < branch_blend_m`` the seven parameters pass smoothly from the lower set to
    the upper one (:func:`branch_weight`) [reconstructed regularisation, default 0.1 mm]: the
    literal switch makes the force jump by ``c_upper - c_lower`` (about 700 N) at x = 0, where
    a vehicle at rest starts, and no fixed-step integrator converges there.
    Default values: identified from the reference damper's loops by the paper's procedure
    (per branch and current fits; d = mean over currents; a, b, c refitted and made linear in
    current; ``python -m capsule_env.identify --emit-defaults``), with the literal branch split
    ``x >= 0`` / ``x < 0`` (``fit_bi_exponential(loops, branch_gap_m=0.0)``). Today's
    ``--emit-defaults`` leaves out the samples within ``branch_blend_m`` of ``x = 0`` (two of
    1000 per loop) and differs by up to 0.58 %; the defaults were kept (docs/model.md 6).
    """

    upper_a0: float = 683.33
    upper_a1: float = 2355.0
    upper_b0: float = 7934.0
    upper_b1: float = 7596.9
    upper_c0: float = 346.01
    upper_c1: float = -82.488
    upper_d: float = 118.68
    lower_a0: float = 683.01
    lower_a1: float = 2353.3
    lower_b0: float = 7939.7
    lower_b1: float = 7608.8
    lower_c0: float = -362.3
    lower_c1: float = 87.897
    lower_d: float = 119.0
    max_current_a: float = 1.5
    coil_time_constant_s: float = 0.0
    branch_blend_m: float = 1e-4
    code: ClassVar[int] = BI_EXPONENTIAL
    name: ClassVar[str] = "bi_exponential"

    def __post_init__(self) -> None:
        self._validate_common()
        check_positive("upper_d", self.upper_d)
        check_positive("lower_d", self.lower_d)
        _check_blend(self.branch_blend_m)


def _check_blend(width_m: float) -> None:
    if not 1e-7 <= width_m <= 1e-2:
        raise ValueError(
            f"branch_blend_m must be in [1e-07, 0.01] m (the stroke band over which the "
            f"sign-of-stroke branch switches), got {width_m!r}"
        )


DamperParams = LinearDamper | ReferenceDamper | BoucWenDamper | TanhDamper | BiExponentialDamper
_CLASSES = {
    "passive": LinearDamper,
    "reference": ReferenceDamper,
    "bouc_wen": BoucWenDamper,
    "tanh": TanhDamper,
    "bi_exponential": BiExponentialDamper,
}


def _check_bouc_wen_shape(gamma: float, beta: float) -> None:
    """Bounded Bouc-Wen loop (n = 2): gamma >= 0 and gamma + beta > 0.

    Loading saturates at ``sqrt(A / (gamma + beta))``; unloading moves towards
    ``sqrt(A / (beta - gamma))``, which lies inside the saturation level only if gamma >= 0.
    """
    if not (gamma >= 0.0 and gamma + beta > 0.0):
        raise ValueError(
            "gamma must be >= 0 and gamma + beta > 0 for a bounded hysteresis loop, got "
            f"gamma={gamma!r}, beta={beta!r}"
        )


def make_damper(name: str, **overrides: float) -> DamperParams:
    """Build a damper model by name (one of :data:`DAMPER_NAMES`) with parameter overrides.

    Raises ``ValueError`` naming the parameter for an unknown model or an unknown/bad parameter.
    """
    check_choice("damper model", name, DAMPER_NAMES)
    cls = _CLASSES[name]
    known = {f.name for f in fields(cls)}
    for key in overrides:
        if key not in known:
            raise ValueError(
                f"unknown parameter {key!r} for damper model {name!r}; accepted: "
                f"{', '.join(sorted(known))}"
            )
    return cls(**overrides)


# --------------------------------------------------------------------------- compiled core


@njit(cache=True, error_model="numpy", inline="always")
def branch_weight(x: float, width_m: float) -> float:
    """Weight of the upper (x >= 0) branch of a sign-of-stroke model: 0 for ``x <= -width_m``,
    1 for ``x >= width_m``, the smoothstep ``s^2 (3 - 2 s)`` of ``s = (1 + x / width_m) / 2`` in
    between (continuous force and slope; no branch, so loops over vehicles vectorise)."""
    s = min(max(0.5 + 0.5 * x / width_m, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True)
def branch_weights(x: np.ndarray, width_m: float) -> np.ndarray:
    """:func:`branch_weight` of every element of a 1-D array (numpy callers: identification)."""
    out = np.empty(x.shape[0])
    for k in range(x.shape[0]):
        out[k] = branch_weight(x[k], width_m)
    return out


@njit(cache=True, error_model="numpy", inline="always")
def bi_exponential_branch(p, x: float):
    """The Bi-exponential parameters ``(a0, a1, b0, b1, c0, c1, d)`` at stroke ``x``: the lower
    set plus :func:`branch_weight` times (upper - lower)."""
    w = branch_weight(x, p[BRANCH_BLEND])
    up, lo = BX_UPPER, BX_LOWER
    return (
        p[lo + BX_A0] + w * (p[up + BX_A0] - p[lo + BX_A0]),
        p[lo + BX_A1] + w * (p[up + BX_A1] - p[lo + BX_A1]),
        p[lo + BX_B0] + w * (p[up + BX_B0] - p[lo + BX_B0]),
        p[lo + BX_B1] + w * (p[up + BX_B1] - p[lo + BX_B1]),
        p[lo + BX_C0] + w * (p[up + BX_C0] - p[lo + BX_C0]),
        p[lo + BX_C1] + w * (p[up + BX_C1] - p[lo + BX_C1]),
        p[lo + BX_D] + w * (p[up + BX_D] - p[lo + BX_D]),
    )


# One force law per model, written without branches or library calls (exp and tanh from
# capsule_env._fastmath), so that the plant's SIMD loop over vehicles vectorises; the same
# functions serve the scalar kernel, the damper test rig and ``damper_force``. ``p``: the packed
# parameters (an array row or a tuple), ``i``: the actual coil current (A).


@njit(**FAST, **BORROWED)
def spencer_inv_dashpots(p, i: float) -> float:
    """``1 / (c0 + c1)`` of the reference (Spencer) damper at current ``i``."""
    return 1.0 / ((p[SP_C0A] + p[SP_C0B] * i) + (p[SP_C1A] + p[SP_C1B] * i))


@njit(**FAST, **BORROWED)
def spencer_force(p, x: float, v: float, y: float, z: float, i: float, inv_c: float):
    """Reference (Spencer) damper: ``(F, y')`` with ``inv_c = 1 / (c0 + c1)`` at ``i``
    (:func:`spencer_inv_dashpots`, computed ahead, off the integrator's dependency chain)."""
    c0 = p[SP_C0A] + p[SP_C0B] * i
    c1 = p[SP_C1A] + p[SP_C1B] * i
    alpha = p[SP_ALPHA_A] + p[SP_ALPHA_B] * i
    y_dot = (alpha * z + c0 * v + p[SP_K0] * (x - y)) * inv_c
    return c1 * y_dot + p[SP_K1] * (x - p[SP_X0]), y_dot


@njit(**FAST, **BORROWED)
def bouc_wen_force(p, x: float, v: float, z: float, i: float) -> float:
    """Bouc-Wen damper (paper eq. 1): ``F = c0 v + k0 (x - x0) + alpha z``."""
    return (
        (p[BW_C0A] + p[BW_C0B] * i) * v
        + p[BW_K0] * (x - p[BW_X0])
        + (p[BW_ALPHA_A] + p[BW_ALPHA_B] * i) * z
    )


@njit(**FAST, **BORROWED)
def tanh_force(p, x: float, v: float, i: float) -> float:
    """Hyperbolic-tangent model (paper eq. 3) with the sign of the stroke blended."""
    sx = 2.0 * branch_weight(x, p[BRANCH_BLEND]) - 1.0
    arg = p[TH_BETA] * v + p[TH_DELTA] * sx
    th = fast_tanh_nonneg(abs(arg))
    th = th if arg >= 0.0 else -th
    force = (
        (p[TH_C_A] + p[TH_C_B] * i) * v
        + (p[TH_K_A] + p[TH_K_B] * i) * x
        + (p[TH_ALPHA_A] + p[TH_ALPHA_B] * i) * th
    )
    return force + p[TH_F0_A] + p[TH_F0_B] * i


@njit(**FAST, **BORROWED)
def bi_exponential_force(p, x: float, v: float, i: float) -> float:
    """Bi-exponential model (paper eq. 4, reconstructed) with the branches blended."""
    a0, a1, b0, b1, c0, c1, d = bi_exponential_branch(p, x)
    mag = 1.0 - fast_exp(-d * abs(v))
    s_d = mag if v >= 0.0 else -mag
    return (a0 + a1 * i) * s_d + (b0 + b1 * i) * v + c0 + c1 * i


@njit(cache=True, inline="always")
def damper_eval(model: int, p: np.ndarray, x: float, v: float, y: float, z: float, i: float):
    """Force and internal rates of one damper of any model (the model a runtime value).

    Returns ``(F, y_dot, w)``: force (N), Spencer's internal velocity y' (m/s; 0 for others)
    and ``w``, the deformation rate that drives the hysteretic variable (``x' - y'`` for the
    reference damper, ``x'`` for Bouc-Wen, 0 for models without one).
    """
    if model == REFERENCE:
        force, y_dot = spencer_force(p, x, v, y, z, i, spencer_inv_dashpots(p, i))
        return force, y_dot, v - y_dot
    if model == BOUC_WEN:
        return bouc_wen_force(p, x, v, z, i), 0.0, v
    if model == TANH:
        return tanh_force(p, x, v, i), 0.0, 0.0
    if model == BI_EXPONENTIAL:
        return bi_exponential_force(p, x, v, i), 0.0, 0.0
    return p[PV_DAMPING] * v, 0.0, 0.0


@njit(cache=True, inline="always")
def hysteresis_params(model: int, p: np.ndarray):
    """``(A, gamma, beta)`` of the model's hysteresis (zeros for models without one)."""
    if model == REFERENCE:
        return p[SP_A], p[SP_GAMMA], p[SP_BETA]
    if model == BOUC_WEN:
        return p[BW_A], p[BW_GAMMA], p[BW_BETA]
    return 0.0, 0.0, 0.0


@njit(cache=True)
def _damper_force_batch(model, params, x, v, i, z, y, force, z_dot, y_dot):
    for k in range(x.shape[0]):
        p = params[k]
        f, yd, w = damper_eval(model, p, x[k], v[k], y[k], z[k], i[k])
        a_coef, gamma, beta = hysteresis_params(model, p)
        force[k] = f
        y_dot[k] = yd
        z_dot[k] = hysteresis_rate(z[k], w, a_coef, gamma, beta) if a_coef > 0.0 else 0.0


def damper_force(
    damper: DamperParams,
    stroke_m: np.ndarray | float,
    stroke_rate_m_per_s: np.ndarray | float,
    current_a: np.ndarray | float,
    state: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Force and internal-state derivative of a damper model, batched (numpy in, numpy out).

    Parameters
    ----------
    damper : a damper parameter dataclass.
    stroke_m, stroke_rate_m_per_s, current_a : broadcastable arrays; current in
        ``[0, damper.max_current_a]`` (A).
    state : ``(..., 2)`` internal state ``[z, y]`` (m); zeros if None.

    Returns
    -------
    force : (N) array, positive when resisting a positive stroke rate.
    state_derivative : ``(..., 2)`` array ``[z', y']``.
    """
    x, v, i = np.broadcast_arrays(
        np.asarray(stroke_m, float),
        np.asarray(stroke_rate_m_per_s, float),
        np.asarray(current_a, float),
    )
    shape = x.shape
    i_max = getattr(damper, "max_current_a", np.inf)
    check_array_in_range("current_a", i, 0.0, i_max)
    if state is None:
        state = np.zeros((*shape, 2))
    state = np.broadcast_to(np.asarray(state, float), (*shape, 2)).reshape(-1, 2)
    n = x.size
    params = np.broadcast_to(damper.as_array(), (n, N_DAMPER_PARAMS))
    force, z_dot, y_dot = np.empty(n), np.empty(n), np.empty(n)
    _damper_force_batch(
        damper.code,
        np.ascontiguousarray(params),
        x.ravel().copy(),
        v.ravel().copy(),
        i.ravel().copy(),
        np.ascontiguousarray(state[:, 0]),
        np.ascontiguousarray(state[:, 1]),
        force,
        z_dot,
        y_dot,
    )
    return force.reshape(shape), np.stack([z_dot, y_dot], axis=-1).reshape(*shape, 2)
