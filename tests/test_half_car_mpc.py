"""The half-car's semi-active MPC (capsule_env.agents.controllers.half_car_mpc).

The independent check: unconstrained, the plan's first moves are the coupled discrete LQ law
of capsule_env.agents.controllers.wheelbase (``lq-discrete-biexp-meas`` and
``wheelbase-lq-biexp-meas``), whose model and Riccati design are built by other code."""

from __future__ import annotations

import numpy as np
import pytest
from capsule_env.agents.controllers.half_car_mpc import (
    HalfCarMPC,
    condense_coupled,
    coupled_lq,
    coupled_model,
)
from capsule_env.agents.controllers.mpc_qp import band_edges
from capsule_env.agents.controllers.mpc_solver import BandQP
from capsule_env.agents.controllers.wheelbase import wheelbase_gains

from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv

W = (0.001, 0.1, 3e-8)


@pytest.mark.parametrize("preview", [False, True])
def test_unconstrained_plan_is_the_discrete_lq_law(preview: bool) -> None:
    """Without a coil lag (the wheelbase module's design has none), the MPC's LQ gain is the
    coupled discrete LQ law's (``lq-discrete-biexp-meas``; with the window, the wheelbase
    preview law's) to 1e-9 of the largest gain, and the unconstrained minimiser of the
    condensed QP's first moves is ``-K z`` (to 1e-7) for horizons of 1 and 12 intervals: the
    terminal cost is the infinite-horizon cost-to-go."""
    model = coupled_model(coil_time_constant_s=0.0, preview=preview)
    theirs = wheelbase_gains("half_car", 0.005, 225.0, *W, preview=preview)
    k_lq = np.concatenate([theirs.k_x, theirs.k_u, theirs.k_p], axis=1)
    k_mpc = coupled_lq(model, *W)[-1]
    assert k_mpc.shape == k_lq.shape == (2, 10 + (18 if preview else 0))
    np.testing.assert_allclose(k_mpc, k_lq, rtol=0, atol=1e-9 * abs(k_lq).max())
    z = (
        np.random.default_rng(3).normal(size=(5, model.size))
        * np.r_[[1e-3] * 8, [1e3] * 2, [1e-3] * (model.size - 10)]
    )
    for horizon in (1, 12):
        qp = condense_coupled(model, W, horizon)
        w = -np.linalg.solve(qp.h, qp.f_z @ z.T)
        first = (qp.blocking @ w).reshape(2, horizon, -1)[:, 0]
        expected = -k_lq @ z.T
        np.testing.assert_allclose(first, expected, rtol=0, atol=1e-7 * abs(expected).max())


def test_the_coil_lag_changes_the_law_and_keeps_the_horizon_out() -> None:
    """With the ``hils`` coil lag the design differs from the lag-free one (the check above
    is not vacuous), and its unconstrained plan is still its own LQ law at any horizon."""
    model = coupled_model()
    assert model.lag and model.size == 12
    k = coupled_lq(model, *W)[-1]
    lag_free = wheelbase_gains("half_car", 0.005, 225.0, *W, preview=False).k_x
    assert np.abs(k[:, :8] - lag_free).max() > 1e-3 * np.abs(lag_free).max()
    z = np.random.default_rng(4).normal(size=model.size) * np.r_[[1e-3] * 8, [1e3] * 4]
    for horizon in (1, 10):
        qp = condense_coupled(model, W, horizon)
        first = (qp.blocking @ -np.linalg.solve(qp.h, qp.f_z @ z)).reshape(2, horizon)[:, 0]
        np.testing.assert_allclose(first, -k @ z, rtol=1e-7)


def _recording(monkeypatch: pytest.MonkeyPatch) -> list:
    """Every plan (``z0``, measured rate and stroke, result) made by any BandQP."""
    plans: list = []
    original = BandQP.plan

    def spy(self, z0, rises, rate, stroke, ref_rate, ref_stroke):  # type: ignore[no-untyped-def]
        result = original(self, z0, rises, rate, stroke, ref_rate, ref_stroke)
        plans.append((np.array(rate, dtype=float), np.array(stroke, dtype=float), result))
        return result

    monkeypatch.setattr(BandQP, "plan", spy)
    return plans


@pytest.mark.parametrize("preview", [False, True])
def test_plans_are_dissipative_and_inside_each_dampers_band(monkeypatch, preview: bool) -> None:
    """Over 1.5 s on the hils plant, each damper's planned forces: now, dissipative at its own
    measured stroke rate and inside the band of the inverted model at its own measured stroke
    and rate; one interval on (a rate the plan cannot move, one step of delay), the same at the
    predicted stroke and rate (both exact: no linearisation), wherever that band has a
    dissipative part; two intervals on, dissipative at the predicted rate once the sign
    pattern has settled. The band is active on both dampers (the plan is not the LQ law)."""
    plans = _recording(monkeypatch)
    law = HalfCarMPC(*W, preview=preview)
    env = DeclaredVehicleEnv(vehicle="half_car", setting="hils", observation="measured",
                             action_mode="force", max_force_n=law.max_force_n,
                             episode_length_s=1.5)  # fmt: skip
    obs, _ = env.reset(seed=11)
    for _ in range(299):
        obs, _, terminated, truncated, _ = env.step(law.predict(obs[None])[0][0])
        assert not (terminated or truncated)
    assert len(plans) == 299 and law.counters["fallback_steps"] == 0
    active, tol = np.zeros(2, dtype=int), 1e-6 * law.max_force_n
    for rate_now, stroke_now, result in plans:
        u, rate = result.u.reshape(2, -1), result.rate_m_s.reshape(2, -1)
        stroke = result.stroke_m.reshape(2, -1)
        np.testing.assert_array_equal(rate[:, 0], rate_now)  # the plan starts at the measured
        np.testing.assert_allclose(stroke[:, 0], stroke_now, rtol=1e-12, atol=1e-15)
        for j in (0, 1):
            edges = band_edges(law.damper, stroke[:, j], rate[:, j])
            lo = np.where(rate[:, j] >= 0, np.maximum(edges[0], 0.0), edges[1])
            hi = np.where(rate[:, j] >= 0, edges[1], np.minimum(edges[0], 0.0))
            assert np.all(u[:, j] * np.sign(rate[:, j]) >= -tol)  # dissipative
            meetable = lo <= hi
            assert np.all((u[:, j] >= lo - tol)[meetable])
            assert np.all((u[:, j] <= hi + tol)[meetable])
            if j == 0:
                active += (np.abs(u[:, 0] - lo) < tol) | (np.abs(u[:, 0] - hi) < tol)
        if result.solves < law.solver_options.max_passes:  # the signs assumed are the plan's
            assert np.all(u[:, 2] * np.sign(rate[:, 2]) >= -tol)
    assert np.all(active > 30)


def test_an_episode_on_the_task_env_rides_like_the_discrete_lq() -> None:
    """End to end on ``CapsuleHalfRide-v0``: 2 s, finite actions of shape (2,), no fallback,
    and a ride (RMS of the comfort accelerations) within 3 % of the clipped discrete LQ law's
    on the same episode; the coil current the law estimates (from the task's command columns
    through the lag) is the plant's."""
    import gymnasium as gym
    from capsule_env.agents.controllers.wheelbase import WheelbasePreviewLQ

    acc, est, true = {}, [], []
    mpc = HalfCarMPC(*W)
    for law in (mpc, WheelbasePreviewLQ(*W, preview=False)):
        env = gym.make("CapsuleHalfRide-v0", episode_length_s=2.0)
        obs, _ = env.reset(seed=3)
        batch = env.unwrapped.batch
        rows = []
        for _ in range(399):
            action = law.predict(obs[None])[0][0]
            assert action.shape == (2,) and np.all(np.isfinite(action))
            obs, _, _, _, info = env.step(action)
            rows.append(info["comfort_acceleration_m_s2"].ravel())
            if law is mpc:
                est.append(law._memory["current"].reshape(-1).copy())
                true.append(np.array(batch.signals()["coil_current_a"]).reshape(-1))
        acc[law.name] = np.sqrt(np.mean(np.array(rows)[100:] ** 2))
    assert mpc.counters["vehicle_steps"] == 399 and mpc.counters["fallback_steps"] == 0
    # the estimate at step k+1 (read from the commands) is the plant's current after step k,
    # up to the float32 observation of the commands (observed 4e-8 A)
    np.testing.assert_allclose(np.array(est)[1:], np.array(true)[:-1], rtol=0, atol=1e-5)
    assert np.ptp(np.array(true)) > 0.5  # the currents move (A)
    ratio = acc["mpc-coupled-biexp-meas"] / acc["lq-discrete-biexp-meas"]
    assert 0.97 < ratio < 1.03


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"delay_steps": True}, "delay_steps"),
        ({"r_force": 0.0}, "r_force"),
        ({"horizon_steps": 0}, "horizon_steps"),
        ({"q_stroke": -1.0}, "q_stroke"),
        ({"horizon_steps": 2.5}, "horizon_steps"),
        ({"q_levitation": float("nan")}, "q_levitation"),
        ({"coil_time_constant_s": -0.1}, "coil_time_constant_s"),
        ({"speed_kmh": 0.0}, "speed_kmh"),
        ({"max_force_n": 0.0}, "max_force_n"),
        ({"preview": "yes"}, "preview"),
        ({"move_blocks": (3, 3)}, "move_blocks"),
        ({"move_blocks": 10}, "move_blocks"),
        ({"solver": {"backend": "cvx"}}, "backend"),
        ({"solver": {"max_passes": 0}}, "max_passes"),
    ],
)
def test_bad_input_names_the_parameter(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        HalfCarMPC(**kwargs)


def test_numpy_scalars_are_taken_as_their_values() -> None:
    """numpy scalars (a ``np.bool_`` preview, as ``SolverOptions.polish`` takes one; numpy
    integers and floats) build the same law as the Python values."""
    law = HalfCarMPC(np.float64(0.001), np.float64(0.1), 3e-8, preview=np.bool_(True),
                     horizon_steps=np.int64(10))  # fmt: skip
    assert law.name == "wheelbase-mpc-biexp-meas" and law.model.window == 18
    np.testing.assert_array_equal(law.qp.h, HalfCarMPC(0.001, 0.1, 3e-8, preview=True).qp.h)


def test_tuning_names_the_mpc_it_tunes() -> None:
    from capsule_env.evaluation.half_car import TUNED_MPC, tune_mpc

    assert set(TUNED_MPC) == {"mpc-coupled-biexp-meas", "wheelbase-mpc-biexp-meas"}
    for name in ("mpc-biexp-meas", ["mpc-coupled-biexp-meas"], None):
        with pytest.raises(ValueError, match="name must be one of"):
            tune_mpc(name)


@pytest.mark.parametrize("seeds", [[1.5], [], "ab", 3, [True]])
def test_tuning_refuses_seeds_that_are_not_episode_seeds(seeds) -> None:
    """``tune_mpc``'s ``seeds`` (through ``rollout``): a list of integer episode seeds; a
    float was truncated (1.5 ran the grid on episode 1), a string, an int or an empty list
    failed elsewhere without naming them."""
    from capsule_env.evaluation.half_car import tune_mpc

    with pytest.raises((TypeError, ValueError), match="seeds"):
        tune_mpc("mpc-coupled-biexp-meas", seeds=seeds)


def test_a_non_finite_observation_requests_0_n_for_that_vehicle_only() -> None:
    """A NaN in one vehicle's observation: 0 N (action 0) for it, counted; the other vehicle
    is planned as usual, bit for bit as without the bad one beside it."""
    env = DeclaredVehicleEnv(vehicle="half_car", setting="hils", observation="measured")
    obs, _ = env.reset(seed=2)
    for _ in range(5):
        obs, *_ = env.step(np.array([0.3, -0.2]))
    pair, alone = HalfCarMPC(*W), HalfCarMPC(*W)
    bad = np.stack([obs, obs]).astype(np.float64)
    bad[1, 4] = np.nan
    actions = pair.predict(bad)[0]
    np.testing.assert_array_equal(actions[1], [0.0, 0.0])
    assert np.all(np.isfinite(actions)) and np.any(actions[0] != 0.0)
    np.testing.assert_array_equal(actions[0], alone.predict(obs[None].astype(np.float64))[0][0])
    assert pair.counters["nonfinite_steps"] == 1 and pair.counters["fallback_steps"] == 0


def _hils_observations(seed: int, steps: int) -> np.ndarray:
    """The half-car's measured observations of ``steps`` steps under a fixed action."""
    env = DeclaredVehicleEnv(vehicle="half_car", setting="hils", observation="measured")
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    for _ in range(steps - 1):
        obs, *_ = env.step(np.array([0.3, -0.2]))
        rows.append(obs)
    return np.array(rows, dtype=np.float64)


@pytest.mark.parametrize("preview", [False, True])
def test_episode_start_resets_that_vehicle_only(preview: bool) -> None:
    """In a vector env (SB3's ``episode_start``), a vehicle whose episode starts is planned as
    by a fresh law, its requests in flight, window, coil current and plan forgotten; the
    other vehicle goes on exactly as it would have."""
    one, two = _hils_observations(2, 12), _hils_observations(5, 12)
    law, other = HalfCarMPC(*W, preview=preview), HalfCarMPC(*W, preview=preview)
    for k in range(8):
        law.predict(np.stack([one[k], two[k]]))
        other.predict(two[k][None])
    start, fresh = np.array([True, False]), HalfCarMPC(*W, preview=preview)
    for k in range(3):  # vehicle 0 restarts on the other seed's first observations
        pair = law.predict(np.stack([two[k], two[8 + k]]), episode_start=start)[0]
        np.testing.assert_array_equal(pair[0], fresh.predict(two[k][None])[0][0])
        np.testing.assert_array_equal(pair[1], other.predict(two[8 + k][None])[0][0])
        start = np.array([False, False])
    with pytest.raises(ValueError, match="episode_start"):  # one flag per vehicle
        law.predict(np.stack([two[3], two[11]]), episode_start=np.array([True, False, False]))


def test_the_preview_tasks_observation_is_read_and_others_refused() -> None:
    """On ``CapsuleHalfRidePreview-v0``'s observation (the measured 16 columns, then each
    bogie's survey) the law reads the measured columns: the same actions as on them alone. An
    observation that is not the half-car's measured one (``full_state``, 17 columns; the
    quarter-car's 9) raises one ``ValueError`` naming the observation."""
    env = DeclaredVehicleEnv(vehicle="half_car", setting="hils", observation="measured",
                             preview_points=32, preview_horizon_s=0.5)  # fmt: skip
    obs, _ = env.reset(seed=2)
    assert obs.shape == (80,)
    with_survey, alone = HalfCarMPC(*W, preview=True), HalfCarMPC(*W, preview=True)
    for _ in range(3):
        action = with_survey.predict(obs[None])[0]
        np.testing.assert_array_equal(action, alone.predict(obs[None, :16])[0])
        obs, *_ = env.step(action[0])
    full = DeclaredVehicleEnv(vehicle="half_car", setting="hils", observation="full_state")
    for bad in (full.reset(seed=2)[0], np.zeros(9)):
        with pytest.raises(ValueError, match="observation"):
            HalfCarMPC(*W).predict(bad[None])


def test_a_wheelbase_window_too_long_to_design_is_refused() -> None:
    """The wheelbase window is 20 m / speed / dt_s intervals (1441 at 10 km/h: a Riccati
    equation of 1450 states, minutes to solve); past 600 the law refuses, naming the lowest
    accepted speed (20 / (600 x 0.005) m/s = 24 km/h); without the window any speed is fine."""
    with pytest.raises(ValueError, match=r"speed_kmh .* above 24(\.\d+)? km/h"):
        HalfCarMPC(*W, preview=True, speed_kmh=10.0)
    with pytest.raises(ValueError, match="dt_s"):
        HalfCarMPC(*W, preview=True, dt_s=1e-4)
    assert HalfCarMPC(*W, preview=True, speed_kmh=50.0).model.window == 289
    assert HalfCarMPC(*W, preview=False, speed_kmh=10.0).model.window == 0


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_a_law_in_mid_episode_copies_and_pickles(backend: str) -> None:
    """``copy.deepcopy`` and ``pickle`` of a law that has planned (its solvers set up): the
    copies go on as the original does, bit for bit with DAQP (its warm start travels), to
    the solver's tolerance with OSQP (set up afresh: a cold start)."""
    import copy
    import pickle

    obs = _hils_observations(2, 8)
    law = HalfCarMPC(*W, preview=True, solver={"backend": backend})
    for k in range(4):
        law.predict(obs[k][None])
    copies = [copy.deepcopy(law), pickle.loads(pickle.dumps(law))]
    for k in range(4, 8):
        ours = law.predict(obs[k][None])[0]
        for other in copies:
            theirs = other.predict(obs[k][None])[0]
            if backend == "daqp":
                np.testing.assert_array_equal(theirs, ours)
            else:
                np.testing.assert_allclose(theirs, ours, rtol=0, atol=0.02)


def test_a_failed_save_leaves_nothing_behind(tmp_path) -> None:
    """``write_json`` (the evaluation's and the MPC check's save) is atomic: a write that
    fails leaves neither the file nor its temporary in the folder, and an old file intact."""
    from capsule_env.evaluation.half_car import write_json

    path = tmp_path / "out.json"
    with pytest.raises(TypeError):
        write_json(str(path), 123)  # not text: the write fails
    assert list(tmp_path.iterdir()) == []
    write_json(str(path), "{}")
    with pytest.raises(TypeError):
        write_json(str(path), 123)
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"] and path.read_text() == "{}"
    (tmp_path / "folder.json").mkdir()
    with pytest.raises(OSError):  # the rename fails: a folder of that name
        write_json(str(tmp_path / "folder.json"), "{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.json", "out.json"]


def test_a_vehicles_plan_does_not_depend_on_the_batch_beside_it() -> None:
    """Each vehicle's actions in a batch of 10 equal, bit for bit, those of the same law run on
    that vehicle alone: the state is rebuilt per vehicle (a batched product's last bits change
    with the batch, and the band's on/off decisions amplify them: episode 1000's Wk moved by
    0.25 % between a batch of 1 and of 10)."""
    seqs = np.stack([_hils_observations(seed, 20) for seed in range(10)])  # (10, 20, 16)
    batched = HalfCarMPC(*W, preview=True)
    alone = [HalfCarMPC(*W, preview=True) for _ in range(10)]
    for k in range(20):
        together = batched.predict(seqs[:, k])[0]
        for n in range(10):
            np.testing.assert_array_equal(together[n], alone[n].predict(seqs[n, k][None])[0][0])
