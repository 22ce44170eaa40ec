"""The half-car task (CapsuleHalfRide-v0): its registration, its comfort metric and the laws
that read its measured signals (capsule_env.evaluation.half_car,
capsule_env.agents.controllers.declared_lqr)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from capsule_env.agents.controllers.declared_lqr import DeclaredClippedLQR, IndependentClippedLQR

from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv
from capsule_env.evaluation import half_car
from capsule_env.metrics import we_weighting


def test_the_task_is_registered_with_two_dampers():
    env = gym.make("CapsuleHalfRide-v0")
    assert isinstance(env.unwrapped, DeclaredVehicleEnv)
    assert env.action_space.shape == (2,)
    assert env.unwrapped.config.effective_sensor_noise == 1.0  # hils
    assert env.unwrapped.config.effective_control_delay_steps == 1
    assert env.unwrapped.vehicle_model.name == "half_car"
    assert len(env.unwrapped.observation_names) == 16  # 8 measured columns per bogie


def test_we_is_iso_2631_1s_rotational_weighting():
    """ISO 2631-1 Annex A with Table 3's We (f1 0.4, f2 100, f3 = f4 = 1 Hz, Q4 0.63, no
    upward step), each factor's magnitude computed here by hand."""
    for f in (1.0, 4.0):
        r1, r2 = f / 0.4, f / 100.0
        high = r1**2 / abs(complex(1 - r1**2, np.sqrt(2) * r1))
        low = 1 / abs(complex(1 - r2**2, np.sqrt(2) * r2))
        transition = abs(complex(1, f)) / abs(complex(1 - f**2, f / 0.63))
        assert abs(abs(we_weighting(np.array([f]))[0]) - high * low * transition) < 1e-12


def test_the_pitch_is_read_from_the_floors_ends():
    """``(a_front - a_rear) / (a + b)`` is the plant's own pitch acceleration (a rigid body:
    exact to rounding)."""
    env = DeclaredVehicleEnv(vehicle="half_car", setting="hils", episode_length_s=0.2)
    env.reset(seed=0)
    batch = env.batch
    wheelbase = batch.values["front_bogie_position_m"] - batch.values["rear_bogie_position_m"]
    pitch_column = batch.n_slots + 1  # the outputs: forces, then z_c'', theta'', ...
    for _ in range(20):
        _, _, _, _, info = env.step(np.array([0.3, -0.2]))
        acc = info["comfort_acceleration_m_s2"]
        pitch = batch.out[0, pitch_column]
        assert abs((acc[0] - acc[2]) / wheelbase - pitch) <= 1e-12 * max(1.0, abs(pitch))


def test_the_measured_coupled_lqr_reads_the_full_states_relative_state():
    """Fed the true ends' velocities in its estimate columns, the measured law rebuilds the
    relative state the full-state law reads (strokes and gaps are measured directly)."""
    full = DeclaredClippedLQR("half_car")
    meas = DeclaredClippedLQR("half_car", observation="measured")
    env = DeclaredVehicleEnv(vehicle="half_car", observation="full_state", episode_length_s=0.5)
    obs, _ = env.reset(seed=3)
    batch = env.batch
    for _ in range(30):
        obs, *_ = env.step(np.array([0.5, 0.1]))
    sig = batch.signals()
    q, v = batch.positions_rates()
    ends = v @ batch.end_rows.T  # upper, lower per slot
    measured = np.zeros((1, 16))
    for s in range(2):
        measured[0, 8 * s + 0] = sig["stroke_m"][0, s]
        measured[0, 8 * s + 4] = sig["gap_m"][0, s]
        measured[0, 8 * s + 5], measured[0, 8 * s + 6] = ends[0, 2 * s], ends[0, 2 * s + 1]
    np.testing.assert_allclose(
        meas.relative_state(measured),
        full.relative_state(batch.observe(sig).astype(np.float64)),
        rtol=1e-5,
        atol=1e-7,
    )  # float32 full-state observation


def test_the_independent_law_is_the_quarter_cars_per_bogie():
    from capsule_env.agents.controllers.classical import make_controller

    law, quarter = IndependentClippedLQR(), make_controller("lqr-clipped-biexp-meas")
    obs = np.random.default_rng(0).normal(size=(3, 16)) * 0.01
    for s in range(2):
        x = obs[:, [8 * s, 8 * s + 5, 8 * s + 4, 8 * s + 6]]  # stroke, v_up, gap, v_low
        expected = np.clip(-(x @ quarter.gain) / 8000.0, -1, 1)
        np.testing.assert_allclose(law.act(obs)[:, s], expected, rtol=1e-12)


def test_the_evaluation_reports_three_floor_points_and_refuses_bad_input(capsys):
    roll = half_car.rollout(IndependentClippedLQR(), [1000, 1001], 2026, length_s=1.0)
    m = half_car.episode_metrics(roll)
    wk = np.stack([m["wk_front_m_s2"], m["wk_centre_m_s2"], m["wk_rear_m_s2"]])
    np.testing.assert_allclose(m["wk_rms_body_acc_m_s2"], wk.mean(axis=0), rtol=1e-15)
    assert np.all(m["we_rms_pitch_rad_s2"] > 0)
    assert half_car.main(["--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--episodes" in err[0]


def test_the_sb3_vecenv_follows_sb3s_conventions_and_the_single_env():
    """Vehicle 0 of ``seed(s)`` runs the single env seeded ``s``; an episode's end resets it in
    the same step, its last observation and the time limit in its info."""
    pytest.importorskip("stable_baselines3")
    from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv

    kwargs = {**half_car.TASK_KWARGS, "episode_length_s": 0.1}  # 20 steps
    venv = DeclaredSB3VecEnv(3, **kwargs)
    venv.seed(7)
    obs = venv.reset()
    single = DeclaredVehicleEnv(**kwargs)
    first, _ = single.reset(seed=7)
    np.testing.assert_array_equal(obs[0], first)
    rng = np.random.default_rng(0)
    for t in range(20):
        act = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        obs, reward, dones, infos = venv.step(act)
        o, r, terminated, truncated, _ = single.step(act[0])
        assert reward[0] == np.float32(r)
        if t < 19:
            np.testing.assert_array_equal(obs[0], o)
            assert not dones.any()
    assert dones.all() and all(i["TimeLimit.truncated"] for i in infos)
    np.testing.assert_array_equal(infos[0]["terminal_observation"], o)
    assert truncated and not terminated
    with pytest.raises(ValueError, match="shape"):
        venv.step_async(np.zeros((3, 1)))


def test_a_law_with_memory_starts_each_evaluation_afresh():
    """The wheelbase law keeps its window of the front's rises: a second evaluation with the
    same object gives the first's figures."""
    from capsule_env.agents.controllers.wheelbase import WheelbasePreviewLQ

    law = WheelbasePreviewLQ(0.001, 0.1, 3e-8)
    first = half_car.episode_metrics(half_car.rollout(law, [1000], 2026, length_s=0.5))
    again = half_car.episode_metrics(half_car.rollout(law, [1000], 2026, length_s=0.5))
    assert first["wk_rms_body_acc_m_s2"][0] == again["wk_rms_body_acc_m_s2"][0]
