"""The gain-scheduled clipped LQR (agents/controllers/scheduled_lqr.py) against independent facts: the
fixed LQR where the plant does not change, a Riccati solve on plant matrices built here in
other coordinates, closed-loop stability at every grid speed, linear interpolation."""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents.controllers.lqr import ClippedOptimalController
from capsule_env.agents.controllers.scheduled_lqr import SPEED_COLUMN, ScheduledLQRController
from scipy.linalg import solve_continuous_are

from capsule_env.engine.config import MEASURED_NAMES
from capsule_env.envelope.levitation import (
    eds_coil,
    levitation_damping_n_s_per_m,
    levitation_stiffness_n_per_m,
)
from capsule_env.vehicles import VehicleParams

WEIGHTS = {"q_stroke": 30.0, "q_levitation": 2.0e3, "r_force": 3.0e-9}
KMH = 1.0 / 3.6


def _absolute_plant(vehicle: VehicleParams, k_p: float, c_p: float):
    """The 2-DOF plant in absolute coordinates ``[z_c, z_b, z_c', z_b']`` (guideway at rest),
    from its mass, stiffness and damping matrices: ``(A, B, C_acc, D_acc)``."""
    mass = np.diag([vehicle.car_body_mass_kg, vehicle.bogie_mass_kg])
    ks = vehicle.secondary_stiffness_n_per_m
    stiffness = np.array([[ks, -ks], [-ks, ks + k_p]])
    damping = np.array([[0.0, 0.0], [0.0, c_p]])
    force = np.array([-1.0, 1.0])  # F pushes the body down and the bogie up
    inv = np.linalg.inv(mass)
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv @ stiffness, -inv @ damping]])
    b = np.concatenate([np.zeros(2), inv @ force])[:, None]
    return a, b, a[2:3, :], b[2:3, :]


def _direct_gain(vehicle: VehicleParams, k_p: float, c_p: float) -> np.ndarray:
    """The LQR gain on ``[stroke, z_c', gap, z_b']`` from a Riccati solve in absolute
    coordinates, transformed back."""
    a, b, c_acc, d_acc = _absolute_plant(vehicle, k_p, c_p)
    stroke = np.array([1.0, -1.0, 0.0, 0.0])
    gap = np.array([0.0, 1.0, 0.0, 0.0])
    q = c_acc.T @ c_acc + WEIGHTS["q_stroke"] * np.outer(stroke, stroke)
    q += WEIGHTS["q_levitation"] * np.outer(gap, gap)
    r = d_acc.T @ d_acc + WEIGHTS["r_force"]
    p = solve_continuous_are(a, b, q, r, s=c_acc.T @ d_acc)
    k_abs = np.linalg.solve(r, b.T @ p + d_acc.T @ c_acc)[0]
    # [stroke, z_c', gap, z_b'] = T [z_c, z_b, z_c', z_b']
    t = np.array([[1.0, -1, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
    return k_abs @ np.linalg.inv(t)


def _obs(state: np.ndarray, speed_m_s: np.ndarray) -> np.ndarray:
    """A measured observation with the trip columns: ``state`` rows ``[stroke, z_c', gap,
    z_b']``, the speed after the set's own columns."""
    cols = {name: k for k, name in enumerate(MEASURED_NAMES)}
    obs = np.zeros((len(state), len(MEASURED_NAMES) + 2))
    for k, name in enumerate(("stroke_m", "car_body_velocity_estimate_m_s",
                              "levitation_gap_m", "bogie_velocity_estimate_m_s")):  # fmt: skip
        obs[:, cols[name]] = state[:, k]
    obs[:, len(MEASURED_NAMES)] = speed_m_s
    return obs


def test_fixed_levitation_gives_the_fixed_lqr_gain_at_every_speed():
    fixed = ClippedOptimalController(observation="measured", **WEIGHTS).gain
    sched = ScheduledLQRController(levitation="fixed", observation="measured", **WEIGHTS)
    speeds = np.array([150.0, 400.0, 810.0, 1000.0, 1200.0]) * KMH
    np.testing.assert_allclose(sched.gain_at(speeds), np.tile(fixed, (5, 1)), rtol=1e-9)
    # with EDS the 810 km/h stiffness is the same (the calibration) but c_p is not 0
    eds = ScheduledLQRController(observation="measured", **WEIGHTS).gain_at(810.0 * KMH)[0]
    assert not np.allclose(eds, fixed, rtol=1e-6)


def test_grid_gains_equal_a_direct_riccati_solve_and_stabilise():
    vehicle = VehicleParams()
    sched = ScheduledLQRController(observation="measured", **WEIGHTS)
    coil = eds_coil(vehicle)
    kmh = sched.speeds_m_s / KMH
    assert kmh[0] == pytest.approx(150.0) and kmh[-1] == pytest.approx(1200.0)
    assert np.diff(kmh).max() <= 25.0 + 1e-9
    unstable_open_loop = 0
    for v, gain in zip(sched.speeds_m_s, sched.gain_table):
        k_p = float(levitation_stiffness_n_per_m(v, coil))
        c_p = float(levitation_damping_n_s_per_m(v, coil))
        # 1e-9 of the gain's size: the two Riccati solves (other coordinates) differ by up to
        # 2.4e-10 of the smallest component here, 2.7e-11 of the norm (LAPACK round-off)
        direct = _direct_gain(vehicle, k_p, c_p)
        np.testing.assert_allclose(gain, direct, rtol=0, atol=1e-9 * np.linalg.norm(direct))
        a, b, _, _ = _absolute_plant(vehicle, k_p, c_p)
        t = np.array([[1.0, -1, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
        closed = a - b @ (gain @ t)[None, :]
        assert np.linalg.eigvals(closed).real.max() < 0.0, v
        unstable_open_loop += np.linalg.eigvals(a).real.max() > 1e-9
    # above v_c the EDS damping is negative: the open loop grows, the schedule stabilises it
    assert unstable_open_loop > 0


def test_interpolation_is_linear_in_speed_between_grid_points():
    sched = ScheduledLQRController(observation="measured", **WEIGHTS)
    v, table = sched.speeds_m_s, sched.gain_table
    np.testing.assert_array_equal(sched.gain_at(v), table)  # the grid points themselves
    for j in (0, 7, len(v) - 2):
        assert not np.allclose(table[j], table[j + 1])  # the gain does change there
        frac = np.array([0.0, 0.25, 0.5, 0.9, 1.0])
        expected = (1 - frac)[:, None] * table[j] + frac[:, None] * table[j + 1]
        between = v[j] + frac * (v[j + 1] - v[j])
        np.testing.assert_allclose(sched.gain_at(between), expected, rtol=1e-12)
    # held at the ends
    np.testing.assert_array_equal(sched.gain_at(np.array([1300.0 * KMH])), table[-1:])


def test_the_force_uses_the_gain_at_the_observed_speed():
    sched = ScheduledLQRController(observation="measured", **WEIGHTS)
    rng = np.random.default_rng(3)
    state = rng.normal(0.0, 0.01, (4, 4))
    speeds = np.array([160.0, 420.0, 810.0, 1111.0]) * KMH
    expected = [-state[k] @ sched.gain_at(speeds[k : k + 1])[0] for k in range(4)]
    np.testing.assert_allclose(sched.desired_force(_obs(state, speeds)), expected, rtol=1e-12)
    assert sched.signals_read[-1] == SPEED_COLUMN
    assert sched.env_kwargs["speed_profile"] == "trip" and sched.env_kwargs["levitation"] == "eds"
    assert sched.name == "lqr-sched-biexp-meas"


def test_bad_input_is_refused_naming_the_parameter():
    sched = ScheduledLQRController(observation="measured", **WEIGHTS)
    with pytest.raises(ValueError, match="speed_m_s.*speed_profile='trip'"):
        sched.predict(np.zeros((2, len(MEASURED_NAMES))))
    with pytest.raises(ValueError, match="levitation"):
        ScheduledLQRController(levitation="maglev")
    with pytest.raises(ValueError, match="top_speed_kmh"):
        ScheduledLQRController(top_speed_kmh=100.0)
    with pytest.raises(ValueError, match="grid_step_kmh"):
        ScheduledLQRController(grid_step_kmh=0.0)
    with pytest.raises(ValueError, match="r_force"):
        ScheduledLQRController(r_force=0.0)
    with pytest.raises(ValueError, match="lift_off_speed_kmh"):
        ScheduledLQRController(levitation_params={"lift_off_speed_kmh": 900.0})


def test_on_a_trip_env_the_law_reads_the_env_speed_column():
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

    sched = ScheduledLQRController(observation="measured", **WEIGHTS)
    env = CapsuleSuspensionVectorEnv(num_envs=3, setting="hils", episode_length_s=0.1,
                                     **sched.env_kwargs)  # fmt: skip
    names = env.config.observation_names
    assert names.index(SPEED_COLUMN) == len(MEASURED_NAMES)  # where the law reads it
    assert env.config.levitation == "eds"
    obs, _ = env.reset(seed=[0, 1, 2])
    speeds = obs[:, names.index(SPEED_COLUMN)]
    assert np.all(speeds >= 150.0 * KMH - 1e-6) and np.all(speeds <= 1000.0 * KMH + 1e-6)
    assert len(set(speeds.tolist())) > 1  # each vehicle its own window of the trip
    for _ in range(5):
        action, _ = sched.predict(obs)
        obs, *_ = env.step(action)
    env.close()
    # without a trip the env has no speed column: the law says which one it misses
    env = CapsuleSuspensionVectorEnv(num_envs=1, setting="hils", episode_length_s=0.1,
                                     **{**sched.env_kwargs, "speed_profile": "constant"})  # fmt: skip
    obs, _ = env.reset(seed=[0])
    with pytest.raises(ValueError, match="speed_m_s"):
        sched.predict(obs)
    env.close()


def test_experiment_script_compares_on_the_same_episodes(tmp_path, capsys):
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "scheduled_lqr.py"
    spec = importlib.util.spec_from_file_location("scheduled_lqr_experiment", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    out = tmp_path / "s.json"
    assert script.main(["--episodes", "2", "--speeds", "810", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["guideway_seed"] == 2026 and data["seeds"] == [1000, 1001]
    for block in (data["trip"], data["810_kmh"]):
        assert block["lqr-clipped-biexp-meas"]["ratio_to_fixed"] == 1.0
        sched = block["lqr-sched-biexp-meas"]
        assert 0.5 < sched["ratio_to_fixed"] < 2.0 and sched["ratio_to_fixed"] != 1.0
        assert "ratio_to_fixed" not in block["passive"]
    with pytest.raises(SystemExit):
        script.main(["--speeds", "100"])
    assert "--speeds must lie in [150, 2000]" in capsys.readouterr().err
