"""The env kernel's named structures: EnvParams.from_config, the named EnvState, the delay ring
the kernel owns, and the deprecated names of before (issue 26 item 5)."""

from __future__ import annotations

import copy

import numpy as np

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.env_params import OBS_MEASURED, EnvParams, EnvState
from capsule_env.engine.layout import VEHICLE_FLOAT_NAMES
from capsule_env.plant.params import Route


def test_from_config_hand_checked():
    cfg = EnvConfig(setting="hils", observation="measured", preview_points=4)
    p = EnvParams.from_config(cfg)
    assert p.observation == OBS_MEASURED
    assert p.i_max_a == 1.5 and p.dt_s == 1.0 / 200.0
    assert p.preview_points == 4 and p.preview_step_s == 0.5 / 4
    assert p.noisy and p.noise_std[0] == 0.02 and p.noise_std[10] == 0.01  # hils: x 1
    assert p.noise_pairs.tolist() == [0, 1, 4, 5]  # channels 0-3, 9, 10
    assert p.obs_bounds.shape == (2, 9 + 4)
    assert p.obs_bounds[1, 5] == 2.0 and p.obs_bounds[0, 5] == -0.5  # measured current
    assert p.survey_error.shape == (1, 1)
    sim = EnvParams.from_config(EnvConfig())
    assert not sim.noisy and not np.any(sim.noise_std)
    assert sim.reward_filter.shape == (0, 6)


def test_state_groups_are_views_of_one_block():
    route = Route(np.zeros(3, dtype=np.int64), np.zeros(3), np.ones(3), np.ones(3))
    state = EnvState.allocate(3, 2, route)
    block = state.vehicle_floats
    assert block.shape == (len(VEHICLE_FLOAT_NAMES), 3)
    assert state.delay.shape == (3, 3)
    block[VEHICLE_FLOAT_NAMES.index("applied_current_a")] = 1.25
    block[VEHICLE_FLOAT_NAMES.index("csdc_last_stroke_m"), 1] = 0.5
    block[VEHICLE_FLOAT_NAMES.index("bogie_estimator_state_2"), 2] = 7.0
    block[VEHICLE_FLOAT_NAMES.index("position_error_m"), 0] = 0.1
    block[VEHICLE_FLOAT_NAMES.index("reward_filter_state_8"), 0] = 3.0
    assert state.applied_current.tolist() == [1.25, 1.25, 1.25]
    assert state.csdc[1, 1] == 0.5
    assert state.estimator[3, 2] == 7.0
    assert state.position_error[0] == 0.1
    assert state.reward_filter[7, 0] == 3.0


def test_a_copy_keeps_its_groups_views_of_its_block():
    batch = CapsuleBatch(EnvConfig(setting="hils", observation="measured"), 2)
    batch.seed(0)
    batch.reset()
    for _ in range(5):
        batch.step(np.array([0.3, -0.2]))
    twin = copy.deepcopy(batch)
    assert np.any(twin.env_state.estimator != 0.0)
    twin.reset()
    assert not np.any(twin.env_state.estimator) and not np.any(twin.applied_current)
    assert np.any(batch.env_state.estimator != 0.0)  # the original is untouched


def test_delay_ring_owned_by_the_kernel():
    """Current mode, a delay of 3 steps: the applied current is the command of 3 steps before
    ((a + 1) / 2 * i_max), zero in an episode's first 3 steps, also after a reset."""
    delay = 3
    cfg = EnvConfig(action_mode="current", control_delay_steps=delay)
    batch = CapsuleBatch(cfg, 2)
    batch.seed(1)
    batch.reset()
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (12, 2))
    commands = (actions + 1.0) / 2.0 * 1.5
    start = np.array([0, 0])
    for k in range(12):
        if k == 5:  # vehicle 1 starts a new episode
            batch.reset(np.array([False, True]))
            start[1] = k
        batch.step(actions[k])
        for n in range(2):
            j = k - delay
            expected = commands[j, n] if j >= start[n] else 0.0
            assert batch.applied_current[n] == expected, (k, n)
        assert batch.step_count.tolist() == [k + 1, k + 1 - start[1]]
