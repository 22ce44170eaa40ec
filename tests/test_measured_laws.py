"""The classical laws on measured signals: hand-computed switching, per-vehicle gains, and
that they read only what a capsule measures."""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents import (
    ADDController,
    ClippedOptimalController,
    MixedSkyhookADDController,
    SkyhookController,
    SkyhookTwoStateController,
    classical_controllers,
    make_controller,
)
from capsule_env.agents.controllers.base import MEAS
from capsule_env.agents.controllers.lqr import lqr_gain
from capsule_env.agents.learning.search_space import SEARCH_SPACES

from capsule_env.engine.config import FULL_STATE_NAMES, MEASURED_NAMES
from capsule_env.engine.observations import TRIP_COLUMN_NAMES
from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
from capsule_env.vehicles import VehicleParams

MEASURED_LAWS = [n for n, c in classical_controllers().items() if c.observation == "measured"]


def _meas(body_vel=0.0, body_acc=0.0, rel_vel=0.0, stroke=0.0, gap=0.0, bogie_vel=0.0):
    """A measured observation batch with the given columns (arrays of one length)."""
    cols = np.broadcast_arrays(body_vel, body_acc, rel_vel, stroke, gap, bogie_vel)
    obs = np.zeros((cols[0].size, len(MEASURED_NAMES)))
    for name, value in zip(("car_body_velocity_estimate_m_s", "car_body_acceleration_m_s2",
                            "stroke_rate_m_s", "stroke_m", "levitation_gap_m",
                            "bogie_velocity_estimate_m_s"), cols):  # fmt: skip
        obs[:, MEAS[name]] = value
    return obs


def _trip_names(ctrl) -> tuple[str, ...]:
    """The columns a trip adds after the set's own (a law that asks for a trip reads them)."""
    return TRIP_COLUMN_NAMES if ctrl.env_kwargs.get("speed_profile") == "trip" else ()


def test_mixed_skyhook_add_switches_as_savaresi_and_spelta():
    """alpha = 0.1 s; hard = i_on (a = 2 * 0.9 / 1.5 - 1 = 0.2), soft = 0 A (a = -1)."""
    ctrl = MixedSkyhookADDController(i_on=0.9, alpha=0.1)
    # (z_c', z_c'', x'): z_c'^2 - alpha^2 z_c''^2 and the sign that decides
    triples = np.array([
        [0.01, 0.5, 0.02],    # 1e-4 - 2.5e-3 < 0: ADD region, z_c'' x' > 0 -> hard
        [0.01, 0.5, -0.02],   # ADD region, z_c'' x' < 0 -> soft (though z_c' x' < 0 too)
        [-0.01, 0.5, 0.02],   # ADD region: z_c'' x' > 0 -> hard although z_c' x' < 0
        [0.05, 0.1, 0.02],    # 2.5e-3 - 1e-4 > 0: Skyhook region, z_c' x' > 0 -> hard
        [0.05, -0.1, 0.02],   # Skyhook region: hard although z_c'' x' < 0
        [-0.05, 0.1, 0.02],   # Skyhook region, z_c' x' < 0 -> soft although z_c'' x' > 0
        [0.02, 0.2, 0.01],    # 4e-4 - 4e-4 = 0 (<= 0): ADD region, z_c'' x' > 0 -> hard
    ])  # fmt: skip
    expected_hard = [True, False, True, True, True, False, True]
    obs = _meas(body_vel=triples[:, 0], body_acc=triples[:, 1], rel_vel=triples[:, 2])
    np.testing.assert_array_equal(ctrl.hard(obs), expected_hard)
    a, _ = ctrl.predict(obs)
    np.testing.assert_allclose(a[:, 0], np.where(expected_hard, 0.2, -1.0), rtol=1e-6)
    # alpha = 0 is Skyhook everywhere (except z_c' = 0); a huge alpha is ADD
    sky = MixedSkyhookADDController(i_on=0.9, alpha=0.0).hard(obs)
    np.testing.assert_array_equal(sky, triples[:, 0] * triples[:, 2] > 0)
    add = MixedSkyhookADDController(i_on=0.9, alpha=1e3).hard(obs)
    np.testing.assert_array_equal(add, triples[:, 1] * triples[:, 2] > 0)


def test_add_and_two_state_skyhook_by_hand():
    vel = np.array([0.1, 0.1, -0.1, -0.1])
    acc = np.array([1.0, -1.0, 1.0, -1.0])
    rel = np.array([0.05, 0.05, -0.05, 0.05])
    obs = _meas(body_vel=vel, body_acc=acc, rel_vel=rel)
    add = ADDController(i_on=1.5)  # hard = full current, a = +1
    np.testing.assert_array_equal(add.predict(obs)[0][:, 0], [1.0, -1.0, -1.0, -1.0])
    sky = SkyhookTwoStateController(i_on=0.375)  # a = 2 * 0.375 / 1.5 - 1 = -0.5
    np.testing.assert_array_equal(sky.predict(obs)[0][:, 0], [-0.5, -0.5, -0.5, -1.0])
    assert add.env_kwargs == {"observation": "measured", "action_mode": "current"}
    with pytest.raises(ValueError, match="i_on"):
        ADDController(i_on=2.0)


def test_measured_continuous_skyhook_and_lqr_read_the_measured_columns():
    body, rel, bogie = np.array([0.1, -0.1, 0.1]), np.array([0.05, 0.05, -0.02]), 0.03
    obs = _meas(body_vel=body, rel_vel=rel, bogie_vel=bogie, stroke=0.004, gap=-0.002)
    sky = SkyhookController("bi_exponential", "continuous", c_sky=5e4, observation="measured")
    np.testing.assert_allclose(sky.desired_force(obs), [5e3, 0.0, 0.0])
    lqr = ClippedOptimalController(q_stroke=10.0, q_levitation=1.0, r_force=1e-8,
                                   observation="measured")  # fmt: skip
    k = lqr_gain(VehicleParams(), 10.0, 1.0, 1e-8)
    x = np.stack([np.full(3, 0.004), body, np.full(3, -0.002), np.full(3, bogie)], axis=1)
    np.testing.assert_allclose(lqr.desired_force(obs), -x @ k)
    assert sky.name == "skyhook-cont-biexp-meas" and lqr.name == "lqr-clipped-biexp-meas"


@pytest.mark.parametrize("name", sorted(SEARCH_SPACES))
def test_per_vehicle_gains_act_as_scalar_gains_vehicle_by_vehicle(name):
    space = SEARCH_SPACES[name]
    rng = np.random.default_rng(7)
    n = 32
    units = rng.uniform(0.0, 1.0, (n, len(space.params)))
    gains = space.gains(units)
    ctrl = make_controller(name, **gains)
    d = len(MEASURED_NAMES) if ctrl.observation == "measured" else len(FULL_STATE_NAMES)
    d += len(_trip_names(ctrl))  # the speed and the longitudinal acceleration on a trip
    d += ctrl.env_kwargs.get("preview_points", 0)  # the preview columns come last
    obs = rng.normal(0.0, 0.05, (n, d))
    batched = ctrl.predict(obs)[0][:, 0]
    for k in range(n):
        alone = make_controller(name, **{g: float(v[k]) for g, v in gains.items()})
        assert alone.predict(obs[k : k + 1])[0][0, 0] == batched[k]
        assert ctrl.gains()[next(iter(alone.gains()))][k] == next(iter(alone.gains().values()))
    assert len(set(batched.tolist())) > 2  # the gains (or the observations) matter


@pytest.mark.parametrize("name", MEASURED_LAWS)
def test_measured_laws_read_only_measured_columns(name):
    ctrl = make_controller(name)
    assert ctrl.env_kwargs["observation"] == "measured"
    assert ctrl.uses_unmeasured_signals is False
    points = ctrl.env_kwargs.get("preview_points", 0)
    assert ctrl.preview is (points > 0)  # the surveyed guideway ahead: measured, flagged apart
    preview = (f"preview_ahead_{k}" for k in range(1, points + 1))
    names = (*MEASURED_NAMES, *_trip_names(ctrl), *preview)
    assert set(ctrl.signals_read) <= set(names)
    assert all(k.endswith(("_a", "_s", "_n_s_m", "_rel", "_1_s4", "_1_kg2", "_n_m"))
               for k in ctrl.gains())  # fmt: skip
    # every column it does not read may be garbage: the actions do not change
    rng = np.random.default_rng(0)
    obs = rng.normal(0.0, 0.05, (8, len(names)))
    poisoned = obs.copy()
    unread = [k for k, c in enumerate(names) if c not in ctrl.signals_read]
    poisoned[:, unread] = np.nan
    ctrl.reset()
    first = ctrl.predict(obs)[0]
    ctrl.reset()
    np.testing.assert_array_equal(ctrl.predict(poisoned)[0], first)


def test_measured_law_runs_on_the_measured_env():
    ctrl = make_controller("sh-add-meas")
    env = CapsuleSuspensionVectorEnv(num_envs=2, setting="hils", episode_length_s=0.2,
                                     **ctrl.env_kwargs)  # fmt: skip
    obs, _ = env.reset(seed=[0, 1])
    assert obs.shape == (2, len(MEASURED_NAMES))
    currents = []
    for _ in range(40):
        obs, _, _, _, info = env.step(ctrl.predict(obs)[0])
        currents.append(info["current_command_a"])
    # two states only: 0 A and i_on (up to the float32 action), and both are used
    currents = np.asarray(currents)
    soft, hard = np.isclose(currents, 0.0, atol=1e-6), np.isclose(currents, ctrl.i_on, atol=1e-6)
    assert np.all(soft | hard) and soft.any() and hard.any()
