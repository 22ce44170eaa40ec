"""The lanes kernel's hysteretic update (:mod:`capsule_env.plant.declared_lanes`) against
:func:`capsule_env.dampers.hysteresis.hysteresis_update`, lane by lane, bit for bit (``==``):
on every branch of the exact update (no increment, loading, unloading that stays below zero,
that ends on zero, that crosses it, a zero start of either sign, arguments of ``tanh`` from
about 1e-60 to 100), with Spencer's linear unloading branch (the split loops) and with a Bouc-Wen
damper's ``beta < gamma`` (the per-lane call)."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.dampers import reference
from capsule_env.dampers.base import N_DAMPER_PARAMS
from capsule_env.dampers.hysteresis import hysteresis_update
from capsule_env.plant.declared_lanes import (
    LANES,
    VECTOR_TANH,
    _advance_z,
    _hysteresis_constants,
    _lane_params,
    _work,
)
from capsule_env.plant.glibc_tanh import matches_libm

NC, NE, NS, NK = 2, 1, 2, 1  # two slots, each the stroke of its own coordinate
FORM = NC + NE * 64 + NS * 64**2 + NK * 64**3
SPENCER = reference.ReferenceDamper()


def _increments(rng: np.random.Generator, z0: np.ndarray, a: float, gamma: float, beta: float):
    """Deformation increments for starts ``z0`` that reach each branch of the update."""
    k = np.sqrt(a * (gamma + beta))
    m_zero = np.abs(z0) / a  # the path that brings an unloading z back to zero (p = 0)
    sign = np.sign(z0)
    du = np.where(rng.random(z0.size) < 0.5, 1.0, -1.0) * 10.0 ** rng.uniform(-60, 2, z0.size) / k
    du[0:4] = du[30:46] = 0.0
    du[4:8] = -sign[4:8] * m_zero[4:8]  # unloading exactly to zero
    du[8:16] = -sign[8:16] * m_zero[8:16] * rng.uniform(0.2, 0.99, 8)  # stays below zero
    du[16:24] = -sign[16:24] * m_zero[16:24] * rng.uniform(1.01, 5.0, 8)  # crosses zero
    du[24:28] = np.nextafter(-sign[24:28] * m_zero[24:28], 0.0)
    return du


def _run(
    code: int, form: int, params: np.ndarray, z0: np.ndarray, du: np.ndarray
) -> tuple[np.ndarray, int]:
    w, _, _, _ = _work(NC, NS, NK)
    g = _lane_params(NC, NE, NS, NK, N_DAMPER_PARAMS)
    srow, dpar = g[3], g[5]
    srow[:] = 0.0
    for s in range(NS):
        srow[s, s] = 1.0
    dpar[:] = params[None, :, None]
    xs, z, u0, out = w[1], w[3], w[9], w[4]
    xs[:] = 0.0
    u0[:] = 0.0
    for s in range(NS):
        xs[s] = du[s]  # stroke - y - u0 = du (y = xs[2 NC + s] = 0)
        z[s] = z0[s]
    _hysteresis_constants(code, form, LANES, g)
    _advance_z(code, form, g, LANES, z, xs, u0, out)
    return out.copy(), int(g[8][0])


# glibc_tanh only where it is this machine's C library's tanh: elsewhere the kernel never runs
# it (tests/test_glibc_tanh.py)
@pytest.mark.parametrize("vector_tanh", [False, True] if matches_libm() else [False])
@pytest.mark.parametrize(("gamma", "beta", "split"), [(SPENCER.gamma, SPENCER.beta, 1),
                                                      (3.63e6, 1.0e6, 0)])  # fmt: skip
def test_the_lanes_update_is_hysteresis_update_bit_for_bit(gamma, beta, split, vector_tanh):
    """With the C library's tanh lane by lane, and with glibc_tanh vectorised."""
    form = FORM + (VECTOR_TANH if vector_tanh else 0)
    rng = np.random.default_rng(42)
    params = SPENCER.as_array().copy()
    params[reference.GAMMA], params[reference.BETA] = gamma, beta
    a = params[reference.A]
    z_sat = np.sqrt(a / (gamma + beta))
    for _ in range(20):
        z0 = rng.uniform(-1.2 * z_sat, 1.2 * z_sat, (NS, LANES))
        z0[:, 28] = 0.0
        z0[:, 29] = -0.0
        du = np.stack([_increments(rng, z0[s], a, gamma, beta) for s in range(NS)])
        du[:, 28:30] = -1e-5
        got, flag = _run(reference.MODEL.code, form, params, z0, du)
        assert flag == split  # which path ran
        want = np.array([[hysteresis_update(z0[s, i], du[s, i], a, gamma, beta)
                          for i in range(LANES)] for s in range(NS)])  # fmt: skip
        assert np.isfinite(want).all()
        assert (got.view(np.int64) == want.view(np.int64)).all()  # the same bits, signs of 0 too
