"""A law restarted at an episode's first step (``predict(..., episode_start=...)``) acts as a
fresh instance of it: what a controller object did before does not enter a result.

The independent fact: a law built afresh (same arguments) driving the same env with the same
seeds in closed loop. A law that has run an earlier episode, restarted by ``episode_start``,
must give exactly its actions (bit for bit: the same operations on the same numbers), for every
law with memory: the semi-active MPCs (requests in flight, the Wk filter, the previous plan's
predicted rates and strokes, the QP solver's warm start: DAQP's previous solution changes its
answer's last bits, OSQP's iterate and step size), the preview LQ laws (requests in flight),
the half-car's wheelbase window laws, and the memoryless laws for completeness. In a vector env
a restarted vehicle acts as a fresh law's single vehicle, the others as if nothing happened.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from capsule_env.agents.controllers.classical import make_controller
from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR
from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC
from capsule_env.agents.controllers.wheelbase import (
    SurveyPreviewLQ,
    WheelbaseExactPreviewLQ,
    WheelbasePreviewLQ,
)

from capsule_env.envs import CapsuleSuspensionVectorEnv
from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.evaluation.half_car import TASK_KWARGS

STEPS = 120  # control steps an episode here (0.6 s): every memory is filled and moves
W = (0.001, 0.1, 3e-8)  # the coupled half-car laws' weights
#: The quarter-car laws with memory, and the memoryless scheduled LQR (on its trip).
QUARTER: dict[str, Callable[[], Any]] = {
    "mpc-biexp-meas": lambda: make_controller("mpc-biexp-meas"),
    "preview-mpc-biexp-meas": lambda: make_controller("preview-mpc-biexp-meas"),
    "mpc-wk-cost": lambda: make_controller("mpc-biexp-meas", wk_cost=True),
    "mpc-osqp": lambda: make_controller("mpc-biexp-meas", solver={"backend": "osqp"}),
    "preview-lq-biexp-meas": lambda: make_controller("preview-lq-biexp-meas"),
    "lqr-sched-biexp-meas": lambda: make_controller("lqr-sched-biexp-meas"),
}
#: The half-car's laws (the declared laws a residual rides on among them).
HALF: dict[str, Callable[[], Any]] = {
    "mpc-coupled-biexp-meas": lambda: HalfCarMPC(*W),
    "wheelbase-mpc-biexp-meas": lambda: HalfCarMPC(*W, preview=True),
    "lq-discrete-biexp-meas": lambda: WheelbasePreviewLQ(*W, preview=False),
    "wheelbase-lq-biexp-meas": lambda: WheelbasePreviewLQ(*W),
    "wheelbase-lq-biexp-exact": lambda: WheelbaseExactPreviewLQ(*W),
    "survey-preview-lq-biexp-meas": lambda: SurveyPreviewLQ(*W),
    "lqr-clipped-biexp-meas": IndependentClippedLQR,
}
LAWS = {**QUARTER, **HALF}
#: The laws without memory: restarted or not, the same actions.
MEMORYLESS = {"lqr-sched-biexp-meas", "lqr-clipped-biexp-meas"}


def _env(name: str, law: Any) -> Any:
    """A one-vehicle vector env of the law's task (the ``hils`` setting)."""
    if name in HALF:
        kwargs = {
            k: v for k, v in {**TASK_KWARGS, **law.env_kwargs}.items() if k != "vehicle_params"
        }
        return DeclaredVectorEnv(1, guideway_seed=3, episode_length_s=5.0, **kwargs)
    return CapsuleSuspensionVectorEnv(num_envs=1, guideway_seed=3, episode_length_s=5.0,
                                      setting="hils", **law.env_kwargs)  # fmt: skip


def closed_loop(name: str, law: Any, seed: int, start: bool = True) -> tuple[np.ndarray, ...]:
    """The law's actions (STEPS, slots) driving the env seeded ``seed``, and the observations
    it acted on (STEPS, d); ``episode_start`` set at the first step when ``start``."""
    env = _env(name, law)
    obs, _ = env.reset(seed=[seed])
    actions, seen = [], []
    for t in range(STEPS):
        seen.append(obs[0].copy())
        action = law.predict(obs, episode_start=np.array([start and t == 0]))[0]
        actions.append(action[0].copy())
        obs, _, terminated, truncated, _ = env.step(action)
        assert not (terminated | truncated).any()  # one episode throughout
    env.close()
    return np.array(actions), np.array(seen)


@pytest.mark.parametrize("name", LAWS)
def test_a_restarted_law_acts_as_a_fresh_one(name: str) -> None:
    """After an earlier episode, ``episode_start`` restarts the law: on the next episode it
    gives a fresh instance's actions exactly (each driving its own env: closed loop). Not
    restarted, a law with memory gives other actions (what the restart is for)."""
    make = LAWS[name]
    law, stale_law = make(), make()
    earlier, _ = closed_loop(name, law, seed=40)
    closed_loop(name, stale_law, seed=40)
    restarted, _ = closed_loop(name, law, seed=41)
    stale, _ = closed_loop(name, stale_law, seed=41, start=False)
    fresh, _ = closed_loop(name, make(), seed=41)
    assert np.std(fresh) > 0.01 and not np.array_equal(earlier, fresh)  # the actions move
    assert np.array_equal(stale, fresh) == (name in MEMORYLESS)
    np.testing.assert_array_equal(restarted, fresh)


def _pair(law: Any, rows: tuple[np.ndarray, np.ndarray], starts: np.ndarray) -> np.ndarray:
    """``law``'s actions (T, 2, slots) for two vehicles fed ``rows`` (each (T, d)), with the
    ``episode_start`` flags ``starts`` (T, 2)."""
    return np.array([law.predict(np.stack([rows[0][t], rows[1][t]]), episode_start=starts[t])[0]
                     for t in range(len(starts))])  # fmt: skip


@pytest.mark.parametrize("name", LAWS)
def test_a_restart_in_a_vector_env_is_that_vehicle_s_alone(name: str) -> None:
    """Two vehicles in one law (observations of closed-loop episodes): vehicle 0 runs one
    episode, then restarts on another (its ``episode_start`` flag set), vehicle 1 runs one
    episode throughout. Vehicle 0 then acts as in a fresh law's pair that starts there;
    vehicle 1 as in a pair where vehicle 0 did not restart. (Pairs, not single vehicles: the
    MPC's Wk filter, ``wk_cost``, is a batched product whose last bits depend on the batch's
    size, not on the other rows.)"""
    make, half = LAWS[name], STEPS // 2
    first, second, other = (closed_loop(name, make(), seed=s)[1] for s in (41, 42, 40))
    own = np.concatenate([first[:half], second[: STEPS - half]])
    starts = np.zeros((STEPS, 2), dtype=bool)
    starts[0] = True
    undisturbed = _pair(make(), (own, other), starts)
    starts[half, 0] = True
    got = _pair(make(), (own, other), starts)
    fresh = _pair(make(), (second[: STEPS - half], other[half:]), starts[half:])
    np.testing.assert_array_equal(got[half:, 0], fresh[:, 0])
    np.testing.assert_array_equal(got[:, 1], undisturbed[:, 1])
    assert np.array_equal(got[:, 0], undisturbed[:, 0]) == (name in MEMORYLESS)


@pytest.mark.parametrize("name", ["mpc-biexp-meas", "mpc-coupled-biexp-meas"])
def test_episode_start_needs_one_flag_per_vehicle(name: str) -> None:
    law = LAWS[name]()
    _, seen = closed_loop(name, law, seed=40)
    with pytest.raises(ValueError, match="episode_start"):
        law.predict(np.stack([seen[0], seen[1]]), episode_start=np.array([True, False, True]))
