"""capsule_env.oracle: the open-loop replay is the env's plant, the adjoint gradient is the
derivative of the whole nonlinear simulation (central differences), and the search improves on
every start and on a causal controller."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.engine.config import EnvConfig
from capsule_env.engine.layout import OUT_BODY_ACC, OUT_GUIDEWAY
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, episode_metrics, run_episodes
from capsule_env.oracle import (
    OracleEpisodes,
    RideObjective,
    adjoint_gradient,
    applied_currents,
    clairvoyant_bound,
)

HILS = {"setting": "hils", "guideway_seed": EVALUATION_GUIDEWAY_SEED}
#: The trip task's physics (CapsuleTrip-v0): the route and the EDS levitation change every step.
TRIP = {**HILS, "levitation": "eds", "speed_profile": "trip", "spans": "continuous",
        "payload_range": (-0.3, 0.4)}  # fmt: skip


def _objective_and_gradient(episodes, u, objective):
    states, outputs = episodes.run(np.array([0]), u[None, :])
    acc = outputs[0, :, OUT_BODY_ACC]
    value, wk, d_acc, d_state = objective.value_and_derivatives(acc, states[0], episodes.columns)
    lin = episodes.linearise(0, states[0], acc, u)
    return value, wk, adjoint_gradient(*lin, d_acc, d_state)


@pytest.mark.parametrize(
    ("setting", "max_stroke_m"),
    [("hils", np.inf), ("hils", 0.002), ("sim", np.inf), ("trip", np.inf)],  # 2 mm: the
)  # stroke penalty acts; trip: the trip task's hils plant, its route and k_p(t) per step
def test_adjoint_gradient_matches_central_differences_of_the_simulation(setting, max_stroke_m):
    kwargs = TRIP if setting == "trip" else {**HILS, "setting": setting}
    episodes = OracleEpisodes(kwargs, [1000], 0.5)
    objective = RideObjective(episodes.n_steps, episodes.dt_s, max_stroke_m, 1000.0)
    u = np.random.default_rng(0).uniform(0.2, 1.3, episodes.n_steps)
    value, wk, grad = _objective_and_gradient(episodes, u, objective)
    assert (value > wk) == bool(np.isfinite(max_stroke_m))  # the penalty acts where asked
    h = 1e-4  # A
    for j in (3, 40, 77, episodes.n_steps - 2):
        plus, minus = u.copy(), u.copy()
        plus[j] += h
        minus[j] -= h
        states, outputs = episodes.run(np.array([0, 0]), np.stack([plus, minus]))
        values = [
            objective.value_and_derivatives(outputs[k, :, OUT_BODY_ACC], states[k], [0, 2])[0]
            for k in range(2)
        ]
        central = (values[0] - values[1]) / (2 * h)
        assert abs(central) > 0.0
        assert grad[j] == pytest.approx(central, rel=0.02, abs=1e-7)


@pytest.mark.parametrize("kwargs", [HILS, TRIP], ids=["hils", "trip"])
def test_open_loop_replay_of_a_controllers_currents_is_the_env(kwargs):
    # Skyhook's commands, delayed by the env's control delay, replayed open loop with the
    # env's substeps: the env's recorded body acceleration and guideway, to rounding. On a
    # trip the replay meets the route and the levitation of every step as the env did.
    from capsule_env.agents.controllers.classical import classical_controllers

    ctrl = classical_controllers()["skyhook-cont-biexp"]
    seeds, length_s = [1000, 1001], 0.5 if kwargs is HILS else 2.0
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, **kwargs}, seeds=seeds,
                        episode_length_s=length_s)  # fmt: skip
    delay = EnvConfig.from_kwargs(**kwargs).effective_control_delay_steps
    assert delay == 1
    u = applied_currents(roll, delay)
    episodes = OracleEpisodes(kwargs, seeds, length_s)
    _, outputs = episodes.run(np.arange(2), u, substeps="env")
    env_acc = roll.signals["car_body_acceleration_m_s2"]
    np.testing.assert_allclose(outputs[:, :, OUT_BODY_ACC], env_acc, rtol=0, atol=1e-12)
    env_guideway = roll.signals["guideway_elevation_m"]
    np.testing.assert_allclose(outputs[:, :, OUT_GUIDEWAY], env_guideway, rtol=0, atol=1e-15)


def test_a_trips_schedule_is_its_speed_and_levitation_at_every_step():
    # independent of the kernels: the route's speed over each interval is the trip's mean
    # speed there (the chord), and k_p the coil model's at the interval's mid-time speed
    import dataclasses

    from capsule_env.engine.batch import CapsuleBatch
    from capsule_env.engine.layout import STIFF_LEVITATION
    from capsule_env.envelope.kernel import ENV_LIMIT, ENV_T0
    from capsule_env.envelope.levitation import levitation_stiffness_n_per_m
    from capsule_env.envelope.trips import trip_position_m, trip_speed_m_s

    seeds = [1000, 1001, 1002, 1003]
    episodes = OracleEpisodes(TRIP, seeds, 1.0)
    sched, dt, n_steps = episodes.schedule, episodes.dt_s, episodes.n_steps
    assert sched is not None and sched.speed_mps.shape == (n_steps, len(seeds))
    batch = CapsuleBatch(episodes.config, len(seeds))  # the same draws: each window's start
    batch.seed(seeds)
    batch.reset()
    trip, coil = batch.envelope.trip, batch.envelope.coil
    t_lo = batch.env_state.envelope[ENV_T0][None, :] + dt * np.arange(n_steps)[:, None]
    chord = (trip_position_m(t_lo + dt, trip) - trip_position_m(t_lo, trip)) / dt
    # the positions are up to ~1e6 m: their rounding (1e-10 m) over dt bounds the tolerance
    np.testing.assert_allclose(sched.speed_mps, chord, rtol=0, atol=1e-6)
    assert np.ptp(chord, axis=0).max() > 0.5  # some window accelerates or brakes
    for k, limit in enumerate(batch.env_state.envelope[ENV_LIMIT]):
        own = dataclasses.replace(coil, stiffness_limit_n_per_m=float(limit))
        k_p = levitation_stiffness_n_per_m(trip_speed_m_s(t_lo[:, k] + 0.5 * dt, trip), own)
        np.testing.assert_allclose(sched.vehicle[:, k, STIFF_LEVITATION], k_p, rtol=1e-12)


def test_search_improves_on_every_start_and_on_skyhook():
    from capsule_env.agents.controllers.classical import classical_controllers

    ctrl = classical_controllers()["skyhook-cont-biexp"]
    seeds = [1000, 1001]
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, **HILS}, seeds=seeds, episode_length_s=1.0)
    sky = applied_currents(roll, 1)
    result = clairvoyant_bound({"setting": "hils"}, seeds, 1.0, starts=["zero", sky],
                               max_iter=25, restarts=1)  # fmt: skip
    assert result.start_names == ("zero", "given:1")
    wk = result.wk_rms_body_acc_m_s2
    # the best of the searches is at least as low as each start's own sequence
    assert np.all(wk <= result.start_wk_m_s2.min(axis=1) + 1e-12)
    # ... and lower than what Skyhook reached closed loop (its own currents were a start)
    m_sky = [episode_metrics(roll.select([k]), None)["wk_rms_body_acc_m_s2"] for k in (0, 1)]
    assert np.all(wk < np.array(m_sky))
    # the rollout is the env's plant replayed: its metric is the result's
    metrics = episode_metrics(result.rollout, None)
    assert metrics["wk_rms_body_acc_m_s2"] == pytest.approx(float(np.mean(wk)), rel=1e-9)
    assert np.all(result.currents_a >= 0.0) and np.all(result.currents_a <= 1.5)
    summary = result.summary()
    assert [row["seed"] for row in summary["episodes_detail"]] == seeds
    assert np.all(result.spread_m_s2 >= 0.0) and np.all(result.restart_gain_m_s2 >= 0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"seeds": []}, "seeds must be a non-empty"),
        ({"seeds": [1000], "max_iter": 0}, "max_iter"),
        ({"seeds": [1000], "starts": ["nope"]}, "unknown start"),
        ({"seeds": [1000], "starts": [2.0]}, "constant current"),
        ({"seeds": [1000], "env_kwargs": {"episode_length_s": 3.0}}, "episode_length_s"),
        ({"seeds": [1000], "env_kwargs": {"settting": "hils"}}, "settting"),
        ({"seeds": [1000], "stroke_penalty": -1.0}, "stroke_penalty"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    args = {"env_kwargs": {"setting": "hils"}, "episode_length_s": 0.5, "max_iter": 2, **kwargs}
    with pytest.raises(ValueError, match=match):
        clairvoyant_bound(**args)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"episode_length_s": "1"}, "episode_length_s"),
        ({"episode_length_s": True}, "episode_length_s"),  # a bool is not a number here
        ({"episode_length_s": None}, "episode_length_s"),
        ({"max_iter": "3"}, "max_iter"),
        ({"max_iter": 2.0}, "max_iter"),
        ({"restarts": True}, "restarts"),
        ({"tol": "small"}, "tol"),
        ({"stroke_penalty": False}, "stroke_penalty"),
        ({"seeds": 1000}, "seeds"),
        ({"seeds": [1000.0]}, "seeds\\[0\\]"),
        ({"env_kwargs": [("setting", "sim")]}, "env_kwargs"),
        ({"starts": "zero"}, "starts"),
        ({"starts": [True]}, "starts\\[0\\]"),
    ],
)
def test_a_wrong_type_is_a_type_error_naming_the_argument(kwargs, name):
    """The docstring's promise (the project's rule): a wrong type is a ``TypeError``, never a
    ``ValueError``, and names the argument; checked before any episode is built."""
    args = {"env_kwargs": {"setting": "sim"}, "seeds": [1000], "episode_length_s": 0.5,
            "max_iter": 2, **kwargs}  # fmt: skip
    with pytest.raises(TypeError, match=name) as info:
        clairvoyant_bound(**args)
    assert not isinstance(info.value, ValueError)
    assert "TypeError" in clairvoyant_bound.__doc__ and "ValueError" in clairvoyant_bound.__doc__


@pytest.mark.parametrize("length", [0, -1.0, float("nan"), 0.05])
def test_a_bad_episode_length_value_is_a_value_error(length):
    with pytest.raises(ValueError, match="episode_length_s") as info:
        clairvoyant_bound({"setting": "sim"}, [1000], length, max_iter=2)
    assert not isinstance(info.value, TypeError)
