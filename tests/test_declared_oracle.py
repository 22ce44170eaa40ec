"""The oracle on a declared vehicle (capsule_env.oracle.declared): its episodes are the env's,
its gradient is the objective's (central differences), and it is never worse than a controller
it starts from (the controller's figure measured from the env's own signals)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from capsule_env.agents.controllers.declared_lqr import DeclaredClippedLQR
from test_vehicles import _toy

from capsule_env.metrics import wk_weighted_rms
from capsule_env.oracle.declared import DeclaredEpisodes, declared_oracle
from capsule_env.vehicles import register, unregister

KWARGS = {"vehicle": "seat_toy", "episode_length_s": 0.5}


@pytest.fixture(autouse=True)
def seat_toy():
    register(_toy())
    yield
    unregister("seat_toy")


def test_the_adjoint_gradient_is_the_objectives():
    """Against central differences of the whole objective (step 1e-4 i_max: truncation and
    rounding both near 1e-6 of the gradient): relative 1e-4."""
    ep = DeclaredEpisodes(KWARGS, [3])
    rng = np.random.default_rng(0)
    u = rng.uniform(0, ep.i_max, (ep.n_steps, ep.n_slots))
    _, grad = ep.value_and_gradient(0, u)
    h = 1e-4 * ep.i_max
    for t in (5, 40, 90):
        up, um = u.copy(), u.copy()
        up[t, 0] += h
        um[t, 0] -= h
        central = (ep.value_and_gradient(0, up)[0] - ep.value_and_gradient(0, um)[0]) / (2 * h)
        assert abs(grad[t, 0] - central) <= 1e-4 * np.max(np.abs(grad))


def _lqr_episode(seed: int) -> tuple[np.ndarray, float]:
    """The clipped LQR through the env: its commanded currents (T, slots) and the Wk of the
    comfort point's acceleration it produced, from the env's own infos."""
    law = DeclaredClippedLQR("seat_toy")
    env = gym.make("CapsuleSuspension-v0", **law.env_kwargs, episode_length_s=0.5)
    obs, _ = env.reset(seed=seed)
    currents, acc = [], []
    while True:
        action, _ = law.predict(obs)
        obs, _, terminated, truncated, info = env.step(action[0])
        currents.append(info["current_command_a"])
        acc.append(info["comfort_acceleration_m_s2"][0])
        if terminated or truncated:
            break
    return np.array(currents), float(wk_weighted_rms(np.array(acc), env.unwrapped.config.dt_s))


def test_the_oracle_replays_the_env_and_is_never_worse_than_its_start():
    currents, lqr_wk = _lqr_episode(seed=7)
    ep = DeclaredEpisodes(KWARGS, [7])
    states, outs = ep.run(np.array([0]), currents[None])
    _, replay_wk = ep.value(states, outs)
    # the same plant, the same commands, the same substeps: the closed loop replayed
    assert abs(replay_wk[0] - lqr_wk) <= 1e-9 * lqr_wk
    result = declared_oracle(KWARGS, [7], starts=[currents[None]], max_iterations=15)
    assert result.wk_m_s2[0] <= lqr_wk
    assert result.wk_m_s2[0] <= result.start_wk_m_s2[0].min()
    assert result.currents.shape == (1, ep.n_steps, 1)
    assert np.all((result.currents >= 0) & (result.currents <= ep.i_max))


def test_the_oracle_keeps_within_the_bump_stop_and_says_so():
    """The chosen sequence's largest stroke is reported (the replay's), and it stays within the
    bump stop when a candidate does (7.5 mm here; without the limit the best reaches 7.3 mm)."""
    kwargs = dict(KWARGS, stroke_limit_m=0.0075)
    result = declared_oracle(kwargs, [8], max_iterations=10)
    ep = DeclaredEpisodes(kwargs, [8])
    states, _ = ep.run(np.array([0]), result.currents)
    stroke = np.abs(ep.strokes(states)).max()
    assert stroke == pytest.approx(result.max_stroke_m[0], rel=1e-12)
    assert stroke <= 0.0075
    with pytest.raises(ValueError, match="starts"):
        declared_oracle(KWARGS, [8], starts=[np.zeros((2, 3))])
