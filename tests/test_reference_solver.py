"""Tests of capsule_env.plant.reference_solver against independent facts.

Facts used: the env's fixed-step plant (RK4 with the closed-form hysteresis update, another
integrator of the same equations) at a step 400 times finer than the control step is the
reference solution; a variable-step solver at a tight tolerance must agree with it, and its
error must shrink with the tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.dampers import BiExponentialDamper, BoucWenDamper, LinearDamper
from capsule_env.engine.simulate import simulate
from capsule_env.guideway import GuidewayParams, make_profile
from capsule_env.plant.reference_solver import VariableStepPlant, simulate_variable_step

DURATION_S = 1.0


@pytest.fixture(scope="module")
def road():
    gw = GuidewayParams()
    return make_profile(gw, DURATION_S, seed=3), gw.spacing_m, gw.speed_mps


def _rel_error(out, ref, key):
    return float(np.max(np.abs(out[key] - ref[key])) / np.max(np.abs(ref[key])))


@pytest.mark.parametrize("damper", [BiExponentialDamper(), BoucWenDamper(), LinearDamper()],
                         ids=lambda d: d.name)  # fmt: skip
@pytest.mark.parametrize("method", ["RK45", "LSODA"])
def test_variable_step_agrees_with_a_fine_fixed_step(road, damper, method):
    profile, spacing, speed = road
    steps = int(DURATION_S / 0.005)
    command = np.where(np.arange(steps) % 40 < 20, 1.5, 0.3)  # a switching current
    ref = simulate(damper, profile, spacing, speed, command, DURATION_S, substeps=400)
    errors = []
    for rtol in (1e-4, 1e-8):
        out = simulate_variable_step(damper, profile, spacing, speed, command, DURATION_S,
                                     method=method, rtol=rtol)  # fmt: skip
        errors.append(max(_rel_error(out, ref, k) for k in
                          ("car_body_displacement_m", "bogie_displacement_m",
                           "bogie_velocity_m_s")))  # fmt: skip
    # the fine fixed step is itself accurate to about 1e-5 of the peak (RK4 at 12.5 us)
    assert errors[1] < 2e-4
    assert errors[1] <= errors[0]


def test_state_and_time_advance_by_the_control_step(road):
    profile, spacing, speed = road
    plant = VariableStepPlant(BoucWenDamper(), profile, spacing, speed)
    plant.step(1.5, 0.005)
    plant.step(9.0, 0.005)  # clipped to i_max
    assert plant.time_s == pytest.approx(0.01)
    assert plant.state[6] == 1.5
    force, acc_body, acc_bogie, zg = plant.outputs(1.5)
    assert np.isfinite([force, acc_body, acc_bogie, zg]).all()
    assert plant.nfev > 0


def test_bad_tolerance_is_named(road):
    profile, spacing, speed = road
    with pytest.raises(ValueError, match="rtol"):
        VariableStepPlant(BoucWenDamper(), profile, spacing, speed, rtol=0.0)
