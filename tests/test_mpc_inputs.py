"""The semi-active MPC (agents/controllers/mpc.py) on bad input: a non-finite observation of one vehicle
(a safe action that step, no harm to later steps or to the other vehicles), weights and solver
options of the wrong shape or type (one clear error naming the parameter), and a solver that
fails (warned once, naming the option to change)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from capsule_env.agents.controllers.mpc import MPCController
from capsule_env.agents.controllers.mpc_qp import condense, prediction_model
from capsule_env.agents.controllers.mpc_solver import BandQP, SolverOptions

from capsule_env.engine.config import OBSERVATION_NAMES, EnvConfig
from capsule_env.vehicles import VehicleParams

N_VEHICLES, N_STEPS, BAD_STEP, BAD_VEHICLE = 3, 8, 2, 1


def observation_sequence(ctrl: MPCController, seed: int = 0) -> np.ndarray:
    """(steps, vehicles, columns) random observations of the law's set (millimetres and
    centimetres per second; coil current 0..1.5 A; preview elevations last)."""
    names = OBSERVATION_NAMES[ctrl.observation]
    rng = np.random.default_rng(seed)
    obs = rng.normal(0.0, 5e-3, (N_STEPS, N_VEHICLES, len(names) + ctrl.preview_points))
    obs[..., names.index("coil_current_a")] = rng.uniform(0.0, 1.5, (N_STEPS, N_VEHICLES))
    return obs


def run(ctrl: MPCController, sequence: np.ndarray) -> tuple[np.ndarray, list]:
    """The actions (steps, vehicles) of ``ctrl`` on ``sequence``, and the RuntimeWarnings."""
    actions = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for obs in sequence:
            actions.append(ctrl.predict(obs)[0][:, 0])
    return np.array(actions), [w for w in caught if issubclass(w.category, RuntimeWarning)]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize(
    ("kwargs", "column"),
    [
        ({}, "stroke_m"),
        ({}, "coil_current_a"),
        ({"preview": True}, "preview"),
        ({"wk_cost": True}, "car_body_acceleration_m_s2"),
        ({"observation": "full_state"}, "guideway_elevation_m"),
        ({"solver": {"backend": "osqp"}}, "stroke_rate_m_s"),
    ],
)
def test_a_nonfinite_sample_gives_0_n_once_and_spares_the_others(
    kwargs: dict, column: str, bad: float
) -> None:
    """One bad sample of one vehicle: that vehicle requests 0 (the damper's 0 A) at that step
    and finite forces after it; the other vehicles' actions are bit for bit those of a run
    without it; counted; one warning for two bad samples."""
    clean = MPCController(**kwargs)
    sequence = observation_sequence(clean)
    expected, clean_warnings = run(clean, sequence)
    assert not clean_warnings and np.all(np.isfinite(expected))

    ctrl = MPCController(**kwargs)
    names = OBSERVATION_NAMES[ctrl.observation]
    col = -1 if column == "preview" else names.index(column)
    poisoned = sequence.copy()
    poisoned[BAD_STEP, BAD_VEHICLE, col] = bad
    poisoned[BAD_STEP + 2, BAD_VEHICLE, col] = bad
    actions, caught = run(ctrl, poisoned)

    assert actions[BAD_STEP, BAD_VEHICLE] == 0.0
    assert np.all(np.isfinite(actions))
    assert np.any(actions[BAD_STEP + 3 :, BAD_VEHICLE] != 0.0)  # planned again
    others = [k for k in range(N_VEHICLES) if k != BAD_VEHICLE]
    np.testing.assert_array_equal(actions[:, others], expected[:, others])
    assert ctrl.counters["nonfinite_steps"] == 2
    assert ctrl.counters["fallback_steps"] == 0
    assert len(caught) == 1 and "non-finite observation" in str(caught[0].message)


def test_a_nan_in_a_column_the_law_does_not_read_is_ignored() -> None:
    ctrl = MPCController()
    sequence = observation_sequence(ctrl)
    expected, _ = run(MPCController(), sequence)
    sequence[:, :, OBSERVATION_NAMES["measured"].index("last_current_command_a")] = np.nan
    actions, caught = run(ctrl, sequence)
    np.testing.assert_array_equal(actions, expected)
    assert ctrl.counters["nonfinite_steps"] == 0 and not caught


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_band_qp_does_not_solve_a_nonfinite_state_nor_keep_it(backend: str) -> None:
    """A plan from a NaN state is not solved and leaves the warm start alone: the next plan
    is that of a solver that never saw it."""
    qp = condense(prediction_model(VehicleParams(), 0.005, 0, 0.0), (2.0, 100.0, 3e-8), 5, 0)
    solvers = [BandQP(qp, EnvConfig().inverse_damper, 8000.0, SolverOptions(backend=backend))
               for _ in range(2)]  # fmt: skip
    states = [np.array([8e-3, 0.02, -5e-3, 0.0]), np.array([-3e-3, -0.05, 2e-3, 0.01])]

    def plan(solver: BandQP, z0: np.ndarray):
        rate = z0[1] - z0[3]
        return solver.plan(z0, np.zeros(5), rate, z0[0], np.full(5, rate), np.full(5, z0[0]))

    plan(solvers[0], states[0])
    plan(solvers[1], states[0])
    nan_plan = plan(solvers[0], np.array([np.nan, 0.02, -5e-3, 0.0]))
    assert nan_plan.status == "failed" and nan_plan.u is None and nan_plan.solves == 0
    after, reference = plan(solvers[0], states[1]), plan(solvers[1], states[1])
    assert after.status == reference.status == "solved"
    np.testing.assert_array_equal(after.u, reference.u)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"q_stroke": np.ones((2, 2))}, "q_stroke must be a real number or a 1-D array"),
        ({"q_levitation": []}, "q_levitation must be"),
        ({"r_force": "1e-8"}, "r_force must be"),
        ({"q_stroke": True}, "q_stroke must be"),
        ({"q_stroke": [[1.0], [1.0, 2.0]]}, "q_stroke must be"),
        ({"q_stroke": np.ones(2), "r_force": np.full(3, 1e-8)}, "same length"),
    ],
)
def test_weights_of_the_wrong_shape_or_type_are_refused_up_front(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        MPCController(**kwargs)


def test_per_vehicle_weights_must_match_the_batch() -> None:
    ctrl = MPCController(q_stroke=np.ones(3), r_force=np.full(3, 3e-8))
    obs = observation_sequence(ctrl)[0]  # 3 vehicles: accepted
    assert np.all(np.isfinite(ctrl.desired_force(obs)))
    ctrl = MPCController(q_stroke=np.ones(3))
    with pytest.raises(ValueError, match=r"3 values \(one per vehicle\) for a batch of 4"):
        ctrl.desired_force(np.concatenate([obs, obs[:1]]))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"solver": {"max_iter": True}}, r"max_iter must be an integer in \[1, 1000000\]"),
        ({"solver": {"max_iter": 50.0}}, "max_iter must be an integer"),
        ({"solver": {"polish": "no"}}, "polish must be True or False"),
        ({"solver": {"polish": 1}}, "polish must be True or False"),
        ({"solver": {"max_passes": True}}, "max_passes must be an integer"),
        ({"solver": {"constrained_steps": 2.0}}, "constrained_steps must be an integer"),
        ({"solver": {"eps_abs": True}}, r"eps_abs must be a number in \(0, 1\]"),
        ({"solver": {"eps_rel": "1e-3"}}, "eps_rel must be a number"),
        ({"solver": {"time_limit_s": False}}, r"time_limit_s must be a number in \[0, 10\] s"),
        ({"solver": {"time_limit_s": float("nan")}}, "time_limit_s must be a number"),
        ({"solver": {"secant_m_s": float("inf")}}, "secant_m_s must be a number"),
        ({"solver": {"backend": ["daqp"]}}, "backend must be one of daqp, osqp"),
        ({"solver": "osqp"}, "solver must be a dict"),
        ({"coil_time_constant_s": True}, "coil_time_constant_s must be a number"),
        ({"preview": True, "preview_horizon_s": True}, "preview_horizon_s must be a number"),
    ],
)
def test_options_of_the_wrong_type_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        MPCController(**kwargs)


def test_numpy_numbers_are_accepted_as_plain_ones() -> None:
    ctrl = MPCController(solver={"backend": "osqp", "max_iter": np.int64(50),
                                 "eps_abs": np.float32(1e-3), "polish": np.bool_(False)})  # fmt: skip
    options = ctrl.solver_options
    assert (options.max_iter, options.polish) == (50, False)
    assert type(options.max_iter) is int and type(options.eps_abs) is float
    assert type(options.polish) is bool


@pytest.mark.parametrize(
    ("solver", "match"),
    [
        ({"max_iter": 1}, r"daqp solver failed on 12 of 12 .*12 failed.*'max_iter' \(now 1\)"),
        ({"max_iter": 1, "polish": False, "backend": "osqp"}, r"osqp .*'max_iter'.*eps_abs"),
        ({"time_limit_s": 1e-9}, r"12 over the time limit.*'time_limit_s' \(now 1e-09\)"),
    ],
)
def test_failing_solves_warn_once_naming_the_option(solver: dict, match: str) -> None:
    ctrl = MPCController(solver=solver)
    obs = np.concatenate([observation_sequence(ctrl, seed)[0] for seed in range(4)])
    with pytest.warns(RuntimeWarning, match=match):
        ctrl.desired_force(obs)
    assert ctrl.counters["fallback_steps"] == len(obs) == 12
    _, caught = run(ctrl, observation_sequence(ctrl)[:, :1].repeat(12, axis=1))
    assert not caught  # once per controller
    assert ctrl.counters["fallback_steps"] == 12 * (1 + N_STEPS)


def test_a_few_failed_solves_or_a_healthy_solver_do_not_warn() -> None:
    few = MPCController(solver={"max_iter": 1})
    _, caught = run(few, observation_sequence(few)[:3])  # 9 failures, under the 10
    assert few.counters["fallback_steps"] == 9 and not caught
    healthy = MPCController()
    _, caught = run(healthy, observation_sequence(healthy))
    assert healthy.counters["fallback_steps"] == 0 and not caught
