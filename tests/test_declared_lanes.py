"""The declared plant in lanes (:mod:`capsule_env.plant.declared_lanes`) against the declared
plant one vehicle at a time (:func:`capsule_env.plant.declared.declared_step`): the same
numbers bit for bit (``==``), on the half-car and the quarter-car declaration, ``sim`` and
``hils``, a batch that is no multiple of the lanes, vehicles with different substep counts."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.plant.declared import declared_step
from capsule_env.plant.declared_lanes import LANES, lanes_step, lanes_step_parallel, plant_form

N = LANES + 37  # a full chunk and a partial one


def _batch(vehicle: str, setting: str):
    env = DeclaredVectorEnv(N, vehicle=vehicle, setting=setting, observation="sensors")
    env.reset(seed=7)
    rng = np.random.default_rng(3)
    for _ in range(40):  # away from rest: strokes, hysteresis and currents of every sign
        env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
    return env.batch


def _run(kernel, batch, command, steps):
    x, out = batch.state.copy(), np.zeros_like(batch.out)
    history = []
    for j in range(steps):
        kernel(batch.plant, x, command[j], batch.route, batch.dt, out)
        history.append((x.copy(), out.copy()))
    return history


@pytest.mark.parametrize(("vehicle", "setting"), [("half_car", "hils"), ("half_car", "sim"),
                                                  ("quarter_car", "hils")])  # fmt: skip
def test_the_lanes_are_the_declared_plant_bit_for_bit(vehicle, setting):
    batch = _batch(vehicle, setting)
    code, n, form = batch.damper.code, batch.num_envs, plant_form(batch.plant)
    rng = np.random.default_rng(11)
    i_max = batch.i_max
    # commands spread over every current bin, so the lanes' substep counts differ
    command = rng.uniform(-0.1 * i_max, 1.1 * i_max, (30, n, batch.n_slots))
    assert len(np.unique(batch.plant.substeps)) > 1 or setting == "sim"  # counts differ

    def old(plant, x, c, route, dt, out):
        declared_step(code, 0, n, plant, x, c, route, dt, out)

    def lanes(plant, x, c, route, dt, out):
        lanes_step(code, form, 0, n, plant, x, c, route, dt, out)

    def threaded(plant, x, c, route, dt, out):
        lanes_step_parallel(code, form)(n, plant, x, c, route, dt, out)

    expected = _run(old, batch, command, 30)
    for kernel in (lanes, threaded):
        for (x_old, out_old), (x_new, out_new) in zip(expected, _run(kernel, batch, command, 30),
                                                      strict=True):  # fmt: skip
            assert np.isfinite(x_old).all() and np.abs(x_old).max() > 0.0
            assert (x_new == x_old).all() and (out_new == out_old).all()


def test_a_vehicles_numbers_do_not_depend_on_its_chunk():
    batch = _batch("half_car", "hils")
    code, form = batch.damper.code, plant_form(batch.plant)
    command = np.random.default_rng(5).uniform(0.0, batch.i_max, (batch.num_envs, 2))
    x_all, out_all = batch.state.copy(), np.zeros_like(batch.out)
    lanes_step(code, form, 0, batch.num_envs, batch.plant, x_all, command, batch.route, batch.dt,
               out_all)  # fmt: skip
    x_one, out_one = batch.state.copy(), np.zeros_like(batch.out)
    for n in (0, 5, LANES, batch.num_envs - 1):
        lanes_step(
            code, form, n, n + 1, batch.plant, x_one, command, batch.route, batch.dt, out_one
        )
        assert (x_one[n] == x_all[n]).all() and (out_one[n] == out_all[n]).all()
