"""The declared plant (capsule_env.plant.declared): any vehicle declared as data, integrated
from its declaration; and the env and the clipped LQR over it.

Independent facts: the quarter-car's own kernels (written by hand, unrolled) on the same
episode; a stiff solver (SciPy's Radau) on Newton's equations of a 3-DOF toy written out here;
two quarter-cars declared as one vehicle move as two quarter-cars; a contact behind the
reference point meets the guideway (a + b) / v later.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from capsule_env.agents.controllers.declared_lqr import DeclaredClippedLQR
from scipy.integrate import solve_ivp
from test_vehicles import SeatParams, _toy

from capsule_env.dampers import registry
from capsule_env.engine.simulate import simulate
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv
from capsule_env.envs.declared_vehicle import DeclaredVehicleEnv
from capsule_env.plant.declared import declared_step
from capsule_env.plant.declared_build import (
    declared_output_names,
    declared_plant,
    declared_state_names,
    declared_substep_tables,
)
from capsule_env.plant.params import Route
from capsule_env.plant.substeps import substep_table
from capsule_env.vehicles import (
    DAMPER,
    SPRING,
    Contact,
    Coordinate,
    Element,
    Point,
    VehicleModel,
    register,
    unregister,
)
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR
from capsule_env.vehicles.quarter_car import VehicleParams


def _run(model, values, damper, profile, spacing, speed, commands, dt, substeps=None, state=None):
    """Open loop through the declared plant: (states (T+1, S), outputs (T, O))."""
    plant = declared_plant(model, [values], damper, profile, spacing, dt, substeps=substeps)
    x = np.zeros((1, len(declared_state_names(model)))) if state is None else state.copy()
    out = np.zeros((1, len(declared_output_names(model))))
    route = Route(np.zeros(1, np.int64), np.zeros(1), np.array([speed]), np.ones(1))
    states, outs = [x[0].copy()], []
    cmd = np.atleast_2d(commands)
    for t in range(cmd.shape[0]):
        declared_step(damper.code, 0, 1, plant, x, cmd[t][None, :], route, dt, out)
        states.append(x[0].copy())
        outs.append(out[0].copy())
    return np.array(states), np.array(outs)


@pytest.mark.parametrize("name", sorted(registry.MODELS))
def test_the_quarter_car_declared_moves_as_its_own_kernels(name):
    """Every damper model: the generic loops over the declaration give the hand-unrolled
    kernels' trajectory (the same scheme and substeps; the sums in another order and LLVM's
    contractions: relative 1e-9 of the signal's spread, observed ~1e-13)."""
    damper = registry.MODELS[name].params()
    rng = np.random.default_rng(0)
    profile = np.cumsum(rng.normal(size=3000)) * 1e-4
    dt, steps = 0.005, 300
    cmd = np.abs(rng.normal(size=steps)) * getattr(damper, "max_current_a", 0.0) / 2
    ref = simulate(damper, profile, 1.0, 100.0, cmd, steps * dt, dt)
    states, outs = _run(QUARTER_CAR, QUARTER_CAR.values(), damper, profile, 1.0, 100.0,
                        cmd[:, None], dt, substeps=substep_table(damper, dt))  # fmt: skip
    for col, key in ((1, "body_acc_m_s2"), (0, "damper_force_n"), (2, "bogie_acc_m_s2")):
        r = ref[key][1:]
        assert np.max(np.abs(outs[:, col] - r)) <= 1e-9 * np.std(r)
    body = ref["car_body_displacement_m"]
    assert np.max(np.abs(states[:, 0] - body)) <= 1e-9 * np.std(body)


@pytest.mark.parametrize("name", sorted(registry.MODELS))
def test_its_substep_rule_is_the_quarter_cars(name):
    damper = registry.MODELS[name].params()
    for dt in (0.001, 0.005, 0.02):
        table = declared_substep_tables(QUARTER_CAR, [QUARTER_CAR.values()], [damper], dt)[0]
        # eigenvalues by LAPACK on matrices assembled in another order: a ceil at a bin's
        # edge may flip by one in the last bits
        assert np.max(np.abs(table - substep_table(damper, dt))) <= 1


def _toy_rhs(p: SeatParams, c_slot: float, zg, zg_rate):
    """Newton's equations of the seat toy, written out: seat on car body on bogie on the
    levitation, a linear damper ``c_slot`` in the secondary slot."""
    ms, mc, mb = p.seat_mass_kg, p.car_body_mass_kg, p.bogie_mass_kg
    k1, c1, k2 = p.seat_stiffness_n_per_m, p.seat_damping_n_s_per_m, p.secondary_stiffness_n_per_m
    k3, c3 = p.levitation_stiffness_n_per_m, p.levitation_damping_n_s_per_m

    def rhs(t, x):
        zs, vs, zc, vc, zb, vb = x
        f_seat = k1 * (zs - zc) + c1 * (vs - vc)
        f_sec = k2 * (zc - zb) + c_slot * (vc - vb)
        f_lev = k3 * (zb - zg(t)) + c3 * (vb - zg_rate(t))
        return [vs, -f_seat / ms, vc, (f_seat - f_sec) / mc, vb, (f_sec - f_lev) / mb]

    return rhs


def test_a_three_dof_toy_against_a_stiff_solver():
    """A 3-DOF toy with a passive damper over a smooth guideway (a 1.3 Hz sine sampled every
    2.5 cm, linear between samples as the plant reads it): RK4 at its substeps against Radau
    at rtol 1e-10 on the equations above (RK4's own error at h = 2.5 ms: relative 1e-5)."""
    p = SeatParams(levitation_damping_n_s_per_m=800.0)
    toy = _toy()
    damper = registry.MODELS["passive"].params(damping_n_s_per_m=1.2e4)
    speed, spacing, dt, steps = 20.0, 0.025, 0.005, 400
    xs = np.arange(0, speed * steps * dt + 10, spacing)
    profile = 0.01 * np.sin(2 * np.pi * 1.3 * xs / speed)
    states, outs = _run(toy, toy.values(p), damper, profile, spacing, speed,
                        np.zeros((steps, 1)), dt)  # fmt: skip

    def zg(t):
        return np.interp(speed * t, xs, profile)

    def zg_rate(t):
        j = min(int(speed * t / spacing), len(xs) - 2)
        return (profile[j + 1] - profile[j]) / spacing * speed

    sol = solve_ivp(_toy_rhs(p, 1.2e4, zg, zg_rate), (0, steps * dt), np.zeros(6), method="Radau",
                    rtol=1e-10, atol=1e-13, t_eval=np.arange(steps + 1) * dt, max_step=spacing / speed)  # fmt: skip
    for j in range(3):  # displacements; rates
        for col, ref in ((j, sol.y[2 * j]), (3 + j, sol.y[2 * j + 1])):
            assert np.max(np.abs(states[:, col] - ref)) <= 1e-4 * np.max(np.abs(ref))
    seat_acc = np.gradient(sol.y[1], sol.t)
    assert np.corrcoef(outs[:, 1], seat_acc[1:])[0, 1] > 0.999


def _run_from(model, damper, profile, speed, cmd, dt, table, start_m):
    """Open loop from route position ``start_m`` (the reference point's)."""
    plant = declared_plant(model, [model.values()], damper, profile, 1.0, dt, substeps=table)
    x = np.zeros((1, len(declared_state_names(model))))
    out = np.zeros((1, len(declared_output_names(model))))
    route = Route(np.zeros(1, np.int64), start_m, np.array([speed]), np.ones(1))
    outs = []
    for t in range(cmd.shape[0]):
        declared_step(damper.code, 0, 1, plant, x, cmd[t][None, :], route, dt, out)
        outs.append(out[0].copy())
    return x, np.array(outs)


def _two_quarter_cars() -> VehicleModel:
    """Two independent quarter-cars as one vehicle: the second behind the first by 12 m."""

    @dataclasses.dataclass(frozen=True)
    class TwoParams(VehicleParams):
        spacing_m: float = 12.0

    coords, points, elements = [], [], []
    for side, contact in (("front", "front_guideway"), ("rear", "rear_guideway")):
        for body in ("car_body", "bogie"):
            mass = f"{body}_mass_kg"
            coords.append(Coordinate(f"{side}_{body}_displacement_m", "m", mass,
                                     f"{side}_{body}_velocity_m_s"))  # fmt: skip
            points.append(Point(f"{side}_{body}", ((f"{side}_{body}_displacement_m", 1.0),)))
        elements += [
            Element(SPRING, f"{side}_secondary", f"{side}_car_body", f"{side}_bogie",
                    "secondary_stiffness_n_per_m"),
            Element(DAMPER, f"{side}_damper", f"{side}_car_body", f"{side}_bogie"),
            Element(SPRING, f"{side}_levitation", f"{side}_bogie", contact,
                    "levitation_stiffness_n_per_m"),
        ]  # fmt: skip
    return VehicleModel(
        name="two_quarter_cars", params=TwoParams, coordinates=tuple(coords),
        points=tuple(points),
        contacts=(Contact("front_guideway", 0.0), Contact("rear_guideway", -12.0)),
        elements=tuple(elements), comfort_points=("front_car_body", "rear_car_body"),
        relative_positions=("front_secondary", "front_levitation", "rear_secondary",
                            "rear_levitation"),
    )  # fmt: skip


def test_two_slots_two_contacts_each_its_own_quarter_car():
    """Two quarter-cars declared as one vehicle, each with its own current: each moves as the
    quarter-car alone on its own guideway (the rear's the front's, 12 m later: (a + b) / v)."""
    model = _two_quarter_cars()
    damper = registry.MODELS["bi_exponential"].params()
    rng = np.random.default_rng(3)
    profile = np.cumsum(rng.normal(size=4000)) * 1e-4
    speed, dt, steps = 100.0, 0.005, 200
    cmd = rng.uniform(0, damper.max_current_a, size=(steps, 2))
    table = substep_table(damper, dt)
    _, outs = _run(model, model.values(), damper, profile, 1.0, speed, cmd, dt, substeps=table,
                   state=None)  # fmt: skip
    names = declared_output_names(model)
    ref = simulate(damper, profile, 1.0, speed, cmd[:, 0], steps * dt, dt)
    body_acc = outs[:, names.index("front_car_body_acceleration_m_s2")]
    assert np.max(np.abs(body_acc - ref["body_acc_m_s2"][1:])) <= 1e-9 * np.std(body_acc)
    # the rear on the guideway the front met 12 m earlier, from the same start
    start = 12.0 * np.ones(1)
    _, outs = _run_from(model, damper, profile, speed, cmd, dt, table, start)
    ref = simulate(damper, profile, 1.0, speed, cmd[:, 1], steps * dt, dt)
    rear_acc = outs[:, names.index("rear_car_body_acceleration_m_s2")]
    assert np.max(np.abs(rear_acc - ref["body_acc_m_s2"][1:])) <= 1e-9 * np.std(rear_acc)
    t = np.arange(1, steps + 1) * dt
    rear = outs[:, names.index("rear_guideway_elevation_m")]
    expected = np.interp(12.0 + speed * t - 12.0, np.arange(len(profile)), profile)
    np.testing.assert_allclose(rear, expected, rtol=0, atol=1e-12)


@pytest.fixture
def seat_toy():
    toy = register(_toy())
    yield toy
    unregister("seat_toy")


def test_gym_make_runs_a_three_dof_toy(seat_toy):
    env = gym.make("CapsuleSuspension-v0", vehicle="seat_toy", action_mode="current")
    assert isinstance(env.unwrapped, DeclaredVehicleEnv)
    assert env.action_space.shape == (1,)
    obs, _ = env.reset(seed=1)
    assert obs.shape == env.observation_space.shape
    n = 0
    while True:
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        n += 1
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        if terminated or truncated:
            break
    assert n == env.spec.max_episode_steps or terminated
    # the quarter-car itself still gets its own compiled env
    assert isinstance(gym.make("CapsuleSuspension-v0").unwrapped, CapsuleSuspensionEnv)


@pytest.mark.parametrize("mode", ["current", "force"])
def test_the_declared_env_on_the_quarter_car_is_the_quarter_car_env(mode):
    """The same seed, the same actions: the declared env on the quarter-car's declaration
    gives the compiled env's rewards (relative 1e-9; observed ~1e-14)."""
    a = gym.make("CapsuleSuspension-v0", action_mode=mode, observation="full_state",
                 episode_length_s=2.0)  # fmt: skip
    b = DeclaredVehicleEnv(vehicle="quarter_car", action_mode=mode, episode_length_s=2.0)
    a.reset(seed=5)
    b.reset(seed=5)
    rng = np.random.default_rng(1)
    ra, rb = [], []
    for _ in range(400):
        act = rng.uniform(-1, 1, 1).astype(np.float32)
        _, r1, t1, u1, info_a = a.step(act)
        _, r2, t2, u2, info_b = b.step(act)
        ra.append(r1)
        rb.append(r2)
        assert (t1, u1) == (t2, u2)
        if t1 or u1:
            break
    assert np.max(np.abs(np.subtract(ra, rb))) <= 1e-9 * np.std(ra)
    assert abs(info_a["stroke_m"] - info_b["stroke_m"][0]) <= 1e-9 * 0.02


def test_unsupported_options_are_refused_by_name(seat_toy):
    for key, value in (
        ("speed_range_kmh", (300.0, 800.0)),
        ("levitation", "eds"),
        ("spans", "continuous"),
    ):
        with pytest.raises(ValueError, match=key):
            gym.make("CapsuleSuspension-v0", vehicle="seat_toy", **{key: value})
    with pytest.raises(ValueError, match="observation"):
        gym.make("CapsuleSuspension-v0", vehicle="seat_toy", observation="bogus")
    with pytest.raises(ValueError, match="seat_mass_kg|bogus"):
        gym.make("CapsuleSuspension-v0", vehicle="seat_toy", vehicle_params={"bogus": 1.0})
    env = gym.make("CapsuleSuspension-v0", vehicle="seat_toy")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        env.step(np.zeros(2))


def test_the_clipped_lqr_runs_the_toy_through_the_env(seat_toy):
    """The law's force is ``-K x`` with ``x`` the relative state computed here from the
    plant's own state; through the env it asks the inverse model for it."""
    law = DeclaredClippedLQR("seat_toy")
    env = gym.make("CapsuleSuspension-v0", **law.env_kwargs)
    obs, _ = env.reset(seed=2)
    batch = env.unwrapped.batch
    for _ in range(200):
        x = batch.state[0]
        q, v = x[:3], x[3:6]  # the declared plant's state: q then v
        zg = batch.out[0, -1]
        rel = np.array([q[0] - q[1], v[0], q[1] - q[2], v[1], q[2] - zg, v[2]])
        expected = -law.gain[0] @ rel
        got = law.desired_force(obs[None, :])[0, 0]
        assert abs(got - expected) <= 1e-3 * max(1.0, abs(expected))  # float32 observation
        action, _ = law.predict(obs)
        obs, reward, terminated, truncated, _ = env.step(action[0])
        assert np.isfinite(reward) and not terminated


def test_the_vector_env_is_the_single_env_per_vehicle():
    """``num_envs`` vehicles with ``seed=[s_0, s_1, s_2]`` are the single envs seeded ``s_n``,
    step for step (the hils setting: Spencer's damper with its coil lag, sensor noise, a
    one-step delay; the noise a hash of the vehicle's key, independent of its batch)."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv

    kwargs = {"vehicle": "half_car", "setting": "hils", "observation": "sensors",
              "episode_length_s": 0.25}  # fmt: skip
    seeds = [4, 9, 11]
    vec = gym.make_vec("CapsuleSuspension-v0", num_envs=3, vectorization_mode="vector_entry_point",
                       **kwargs)  # fmt: skip
    assert isinstance(vec.unwrapped, DeclaredVectorEnv)
    assert vec.action_space.shape == (3, 2)
    obs, _ = vec.reset(seed=seeds)
    singles = [DeclaredVehicleEnv(**kwargs) for _ in seeds]
    first = [env.reset(seed=s)[0] for env, s in zip(singles, seeds, strict=True)]
    np.testing.assert_array_equal(obs, np.array(first))
    rng = np.random.default_rng(0)
    for _ in range(60):  # past the end of the first episodes (50 steps): the autoreset
        act = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        obs, reward, terminated, truncated, _ = vec.step(act)
        for n, env in enumerate(singles):
            if env._needs_reset:
                o, _ = env.reset()
                r, done = 0.0, (False, False)
            else:
                o, r, te, tr, _ = env.step(act[n])
                done = (te, tr)
            np.testing.assert_array_equal(obs[n], o)
            assert reward[n] == r and (terminated[n], truncated[n]) == done
