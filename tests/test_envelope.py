"""The operating envelope in the env (issue 28): EDS levitation against speed, trips, spans,
payload. Checked against independent facts: the coil model's closed forms
(capsule_env.envelope.levitation), the trip's exact position (capsule_env.envelope.trips), the beam's sag
(capsule_env.guideway.spans), the linear plant's exact solution (matrix exponential) and its
frequency response, and the constant-speed env itself (bit for bit)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl

from capsule_env.dampers import make_damper
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.layout import (
    DAMP_LEVITATION,
    SIG_GUIDEWAY,
    STATE_SIZE,
    STIFF_LEVITATION,
    TIME,
)
from capsule_env.engine.simulate import simulate
from capsule_env.envelope.levitation import (
    eds_coil,
    levitation_damping_n_s_per_m,
    levitation_stiffness_n_per_m,
)
from capsule_env.envelope.trips import (
    TripParams,
    trip_acceleration_m_s2,
    trip_position_m,
    trip_speed_m_s,
)
from capsule_env.guideway.spans import SpanParams, span_profile
from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.modes import state_space

BASE = {"setting": "hils", "observation": "measured", "episode_length_s": 2.0}


def _run(config: EnvConfig, steps: int = 500, n: int = 3, seed: int = 5):
    batch = CapsuleBatch(config, n)
    batch.seed(seed)
    batch.reset()
    rng = np.random.default_rng(0)
    obs, signals = [batch.obs.copy()], []
    for k in range(steps):
        batch.step(rng.uniform(-1.0, 1.0, n))
        obs.append(batch.obs.copy())
        signals.append(batch.signals.copy())
        if k == 250:  # an autoreset-like masked reset mid-run
            batch.reset(np.array([True, False, True]))
    return np.array(obs), np.array(signals)


def test_a_trip_that_keeps_its_speed_is_the_constant_env_bit_for_bit():
    obs_c, sig_c = _run(EnvConfig(**BASE))
    trip = {"cruise_speed_kmh": 810.0, "lift_off_speed_kmh": 810.0}
    obs_t, sig_t = _run(EnvConfig(**BASE, speed_profile="trip", trip_params=trip))
    assert np.array_equal(obs_c, obs_t[:, :, :-2])
    assert np.array_equal(sig_c, sig_t)
    assert np.all(obs_t[:, :, -2] == np.float32(810.0 / 3.6)) and np.all(obs_t[:, :, -1] == 0.0)


def test_the_guideway_seen_on_a_trip_is_the_profile_at_the_travelled_distance():
    config = EnvConfig(**BASE, speed_profile="trip", trip_params={"cruise_duration_s": 5.0})
    trip = config.envelope.trip
    batch = CapsuleBatch(config, 6)
    batch.seed(3)
    batch.reset()
    t0, start = batch.env_state.envelope[0].copy(), batch.env_state.envelope[1].copy()
    assert len({round(float(trip_acceleration_m_s2(t, trip)), 6) for t in t0}) > 1  # phases
    x_grid = np.arange(batch.profiles.shape[1]) * batch.spacing
    worst = 0.0
    for _ in range(400):
        batch.step(np.zeros(6))
        t = batch.state[:, TIME]
        travelled = trip_position_m(t0 + t, trip) - trip_position_m(t0, trip)
        for n in range(6):
            expect = batch.gain[n] * np.interp(start[n] + travelled[n], x_grid,
                                               batch.profiles[batch.profile_index[n]])  # fmt: skip
            worst = max(worst, abs(expect - batch.signals[SIG_GUIDEWAY, n]))
        np.testing.assert_allclose(batch.obs[:, -2], trip_speed_m_s(t0 + t, trip), rtol=1e-6)
        np.testing.assert_array_equal(batch.obs[:, -1], trip_acceleration_m_s2(t0 + t, trip))
    # the chord's mid-interval error a dt^2 / 8 (3 um) times the slope, and round-off
    assert worst < 1e-9


@pytest.mark.parametrize("speed_kmh", [150.0, 400.0, 810.0, 1200.0])
def test_eds_levitation_is_the_coil_model_at_each_vehicles_speed(speed_kmh):
    config = EnvConfig(**BASE, levitation="eds", speed_kmh=speed_kmh)
    batch = CapsuleBatch(config, 2)
    batch.reset()
    coil = eds_coil(VehicleParams())
    v = speed_kmh / 3.6
    np.testing.assert_allclose(batch.vehicle_params[:, STIFF_LEVITATION],
                               levitation_stiffness_n_per_m(v, coil), rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(batch.vehicle_params[:, DAMP_LEVITATION],
                               levitation_damping_n_s_per_m(v, coil), rtol=1e-12)  # fmt: skip
    if speed_kmh == 810.0:  # the calibration point: the paper's stiffness
        np.testing.assert_allclose(batch.vehicle_params[:, STIFF_LEVITATION], 2.25e6, rtol=1e-12)


def test_eds_on_a_trip_follows_the_speed_every_step():
    config = EnvConfig(**BASE, levitation="eds", speed_profile="trip")
    batch = CapsuleBatch(config, 4)
    batch.seed(11)
    batch.reset()
    coil, trip = eds_coil(VehicleParams()), config.envelope.trip
    t0 = batch.env_state.envelope[0].copy()
    for _ in range(50):
        t = batch.state[:, TIME].copy()
        batch.step(np.zeros(4))
        v_mid = trip_speed_m_s(t0 + t + 0.5 * config.dt_s, trip)
        np.testing.assert_allclose(batch.vehicle_params[:, STIFF_LEVITATION],
                                   levitation_stiffness_n_per_m(v_mid, coil), rtol=1e-9)  # fmt: skip
        np.testing.assert_allclose(batch.vehicle_params[:, DAMP_LEVITATION],
                                   levitation_damping_n_s_per_m(v_mid, coil), rtol=1e-9, atol=1e-9)  # fmt: skip


@pytest.mark.parametrize("speed_kmh", [150.0, 300.0, 810.0, 1200.0])
def test_plant_modes_at_each_speed_are_the_linearised_plants(speed_kmh):
    """Free decay of the plant with EDS k_p(v), c_p(v) and a linear damper equals the exact
    solution expm(A t) x0 of the linear plant: its eigenvalues (the modes) are the plant's."""
    coil = eds_coil(VehicleParams())
    v = speed_kmh / 3.6
    vehicle = VehicleParams(
        levitation_stiffness_n_per_m=float(levitation_stiffness_n_per_m(v, coil)),
        levitation_damping_n_s_per_m=float(levitation_damping_n_s_per_m(v, coil)),
    )
    damper = make_damper("passive")
    x0 = np.zeros(STATE_SIZE)
    x0[2] = 1e-3  # the bogie displaced 1 mm over a flat guideway
    run = simulate(damper, np.zeros(64), 1.0, v, 0.0, 2.0, vehicle=vehicle, state0=x0, substeps=8)
    a, _, _ = state_space(vehicle, damper.damping_n_s_per_m)
    exact = np.array([sl.expm(a * t) @ [0.0, 0.0, 1e-3, 0.0] for t in run["time_s"]])
    # 1e-10 m of a 1e-3 m decay: RK4's error at 8 substeps (~1e-12 m) plus SciPy's expm
    # (Pade, a few ulps relative on any BLAS), with a wide margin
    np.testing.assert_allclose(run["bogie_displacement_m"], exact[:, 2], atol=1e-10)
    np.testing.assert_allclose(run["car_body_displacement_m"], exact[:, 0], atol=1e-10)


def test_levitation_damping_acts_on_the_rate_relative_to_the_guideway():
    """A sine guideway through a plant with a large c_p: the steady-state bogie amplitude is
    the linear plant's |H(j w)| with the input ``(k_p + j w c_p) z_g / m_b``."""
    vehicle = VehicleParams(levitation_damping_n_s_per_m=2e4)
    damper = make_damper("passive")
    f_hz, speed, spacing = 10.0, 100.0, 0.05
    x = np.arange(int(1000.0 / spacing) + 1) * spacing
    profile = 1e-3 * np.sin(2 * np.pi * f_hz * x / speed)
    run = simulate(damper, profile, spacing, speed, 0.0, 8.0, vehicle=vehicle, substeps=20)
    a, _, _ = state_space(vehicle, damper.damping_n_s_per_m)
    w = 2 * np.pi * f_hz
    e = np.array([0.0, 0.0, 0.0, (vehicle.levitation_stiffness_n_per_m + 1j * w * 2e4) / 2400.0])
    gain = abs(np.linalg.solve(1j * w * np.eye(4) - a, e)[2]) * 1e-3
    keep = run["time_s"] > 5.0
    t, tail = run["time_s"][keep], run["bogie_displacement_m"][keep]
    basis = np.stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)], axis=1)
    coef = np.linalg.lstsq(basis, tail, rcond=None)[0]  # the steady sine at the input's w
    assert abs(np.hypot(coef[0], coef[1]) / gain - 1.0) < 2e-3
    # without the rate term the amplitude would differ by far more than that
    e0 = np.array([0.0, 0.0, 0.0, vehicle.levitation_stiffness_n_per_m / 2400.0])
    assert abs(abs(np.linalg.solve(1j * w * np.eye(4) - a, e0)[2]) * 1e-3 / gain - 1.0) > 0.05


def test_spans_are_added_after_the_gain_unscaled():
    plain = CapsuleBatch(EnvConfig(**BASE), 4)
    spanned = CapsuleBatch(EnvConfig(**BASE, spans="simply_supported",
                                     span_params={"span_m": 25.0}), 4)  # fmt: skip
    for b in (plain, spanned):
        b.seed(9)
        b.reset()
    # the random irregularity is the same, with the same per-episode gain (8 mm peak)
    np.testing.assert_array_equal(spanned.profiles, plain.profiles)
    np.testing.assert_array_equal(spanned.gain, plain.gain)
    length = (plain.profiles.shape[1] - 1) * plain.spacing
    seeds = np.random.SeedSequence([0, 2]).generate_state(plain.profiles.shape[0])
    params = SpanParams(span_m=25.0, shape="simply_supported")
    for k in range(plain.profiles.shape[0]):
        np.testing.assert_allclose(spanned.offsets[k], span_profile(length, plain.spacing, params,
                                                                    int(seeds[k])), atol=1e-15)  # fmt: skip
    # the sag at mid-span, L/3000 of 25 m, below the line through the pylons (their settlement)
    j = int(round(25.0 / plain.spacing))
    assert j * plain.spacing == pytest.approx(25.0) and j % 2 == 0
    chord = 0.5 * (spanned.offsets[0, 0] + spanned.offsets[0, j])
    assert chord - spanned.offsets[0, j // 2] == pytest.approx(25.0 / 3000, rel=1e-9)
    # what the vehicles drive over: the random part times the gain, plus the spans unscaled
    x_grid = np.arange(plain.profiles.shape[1]) * plain.spacing
    for _ in range(100):
        plain.step(np.zeros(4))
        spanned.step(np.zeros(4))
    for n in range(4):
        x = spanned.start_position[n] + spanned.speed[n] * spanned.state[n, TIME]
        k = spanned.profile_index[n]
        span_here = np.interp(x, x_grid, spanned.offsets[k])
        assert spanned.signals[SIG_GUIDEWAY, n] - plain.signals[SIG_GUIDEWAY, n] == pytest.approx(
            span_here, abs=1e-12
        )


def test_payload_changes_only_the_car_body_mass_within_its_range():
    config = EnvConfig(**BASE, payload_range=(-0.3, 0.4))
    batch = CapsuleBatch(config, 64)
    batch.seed(2)
    batch.reset()
    ratio = batch.vehicle_params[:, 0] / VehicleParams().car_body_mass_kg
    assert np.all((ratio >= 0.7) & (ratio <= 1.4)) and np.ptp(ratio) > 0.5
    np.testing.assert_array_equal(batch.vehicle_params[:, 1:4],
                                  np.tile(VehicleParams().as_array()[1:4], (64, 1)))  # fmt: skip


def test_trip_task_runs_with_gymnasium_make_and_make_vec():
    import gymnasium as gym

    import capsule_env  # noqa: F401  (registers the ids)

    env = gym.make("CapsuleTrip-v0")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (11,) and env.observation_space.contains(obs)
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    venv = gym.make_vec("CapsuleTrip-v0", num_envs=3, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=1)
    assert obs.shape == (3, 11)
    venv.close()


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"levitation": "magnetic"}, "levitation"),
        ({"levitation": "eds", "speed_kmh": 100.0}, "speed_kmh"),
        ({"levitation_params": {"pole_pitch_m": 1.0}}, "levitation_params"),
        ({"levitation": "eds", "levitation_params": {"pitch": 1.0}}, "pitch"),
        ({"speed_profile": "trip", "trip_params": {"cruise_speed_kmh": -5.0}}, "cruise_speed_kmh"),
        ({"speed_profile": "trip", "speed_range_kmh": (500.0, 900.0)}, "speed_range_kmh"),
        ({"speed_profile": "trip", "levitation": "eds",
          "trip_params": {"lift_off_speed_kmh": 100.0}}, "lift_off_speed_kmh"),
        ({"spans": "arch"}, "spans"),
        ({"spans": "continuous", "span_params": {"shape": "continuous"}}, "shape"),
        ({"payload_range": (0.5, 0.1)}, "payload_range"),
        ({"payload_range": 0.2}, "payload_range"),
        ({"speed_profile": "trip", "speed_kmh": 400.0}, "speed_kmh"),
        ({"levitation": "eds", "vehicle_params": {"levitation_damping_n_s_per_m": 1e3}},
         "levitation_damping_n_s_per_m"),
        ({"vehicle_params": {"levitation_damping_n_s_per_m": 1e6}}, "levitation_damping_n_s_per_m"),
        ({"speed_profile": "trip", "trip_params": {"cruise_speed_kmh": 100.0}},
         "trip_params: cruise_speed_kmh must be >= lift_off_speed_kmh"),
        ({"levitation": "eds", "levitation_params": {"lift_off_speed_kmh": 900.0}},
         "levitation_params: lift_off_speed_kmh"),
        ({"levitation": "eds", "speed_range_kmh": (100.0, 800.0)}, r"speed_range_kmh\[0\]"),
        ({"levitation": "eds", "vehicle_params": {"levitation_stiffness_n_per_m": 1e5}},
         "vehicle_params"),
    ],
)  # fmt: skip
def test_bad_envelope_options_are_named(kwargs, named):
    with pytest.raises((ValueError, TypeError), match=named):
        EnvConfig(**kwargs)


def test_trip_params_are_the_trips():
    """The trip the env runs is trips.TripParams with the given overrides."""
    config = EnvConfig(speed_profile="trip", trip_params={"acceleration_m_s2": 1.5})
    assert config.envelope.trip == TripParams(acceleration_m_s2=1.5)
