"""``experiments/half_car_ppo.py --residual --law wheelbase-mpc-biexp-meas``: the residual on
the half-car's best law, a law with a memory per vehicle, and the ``--learning-rate`` option."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from tests.test_half_car_review import PPO_SCRIPT, _ppo_script, _record_learning_rates

MPC = "wheelbase-mpc-biexp-meas"


def _applied_actions(wrapper, steps: int) -> tuple[list[np.ndarray], list[np.ndarray], list]:
    """Step ``wrapper`` with a zero residual; the observations it acted on, the actions it sent
    on to the env, and the done flags."""
    sent: list[np.ndarray] = []
    step_async = wrapper.venv.step_async

    def spy(actions):
        sent.append(np.array(actions, copy=True))
        step_async(actions)

    wrapper.venv.step_async = spy
    observations, dones = [wrapper.reset()], []
    for _ in range(steps):
        obs, _, done, _ = wrapper.step(np.zeros((wrapper.num_envs, 2)))
        observations.append(obs)
        dones.append(done)
    return observations, sent, dones


def test_the_residual_restarts_the_mpc_with_each_vehicles_episode():
    """With a zero residual the wrapper applies exactly what a fresh MPC applies on each
    episode's observations from its first: the law's memory (the front's rises, the requests
    in flight, the plans) starts afresh when SB3 resets a vehicle. Carrying it across the
    restart changes the second episode's actions."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("daqp")
    from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
    from capsule_env.evaluation.half_car import TASK_KWARGS

    script = _ppo_script()
    venv = DeclaredSB3VecEnv(2, guideway_seed=0, episode_length_s=0.1, **TASK_KWARGS)
    venv.seed(3)
    observations, sent, dones = _applied_actions(script._residual_wrapper(venv, MPC), 30)
    ends = [t for t, d in enumerate(dones) if d.all()]
    assert ends and ends[0] == 19  # 0.1 s of 5 ms steps: the 20th step ends the episode
    start = ends[0] + 1  # the observation that step returns starts the next episode
    for first, last in ((0, start), (start, len(sent))):
        law = script._law(MPC)
        for t in range(first, last):
            flags = np.full(2, t == first)
            expected = law.predict(np.asarray(observations[t], dtype=np.float64),
                                   episode_start=flags)[0]  # fmt: skip
            np.testing.assert_array_equal(sent[t], np.clip(expected, -1.0, 1.0))
    carried = script._law(MPC)  # one law through both episodes, no restart flags
    for t in range(len(sent)):
        carried_action = carried.predict(np.asarray(observations[t], dtype=np.float64))[0]
    assert not np.array_equal(np.clip(carried_action, -1, 1), sent[-1])


def test_the_learning_rate_option_starts_the_linear_schedule(tmp_path, monkeypatch):
    """``--learning-rate 1e-4``: 1e-4 (1 - steps / total) at every update."""
    pytest.importorskip("stable_baselines3")
    script = _ppo_script()
    seen = _record_learning_rates(monkeypatch)
    args = script.Args(tmp_path / "run", seeds=(0,), total_timesteps=384, num_envs=2,
                       checkpoint_every=200, learning_rate=1e-4)  # fmt: skip
    script.train_seed(args, 0)
    steps = np.array([s for s, _ in seen])
    rates = np.array([r for _, r in seen])
    np.testing.assert_array_equal(steps, [128, 256, 384])
    np.testing.assert_allclose(rates, 1e-4 * (1.0 - steps / 384), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["--law", MPC], "--law"),  # a law without --residual
        (["--residual", "--law", "skyhook"], "--law"),
        (["--learning-rate", "0"], "--learning-rate"),
        (["--learning-rate", "nan"], "--learning-rate"),
        (["--learning-rate", "2"], "--learning-rate"),
    ],
)
def test_bad_options_are_refused_in_one_line(tmp_path, argv, names):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, str(PPO_SCRIPT), "--out", str(out), *argv],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert names in lines[-1] and "Traceback" not in proc.stderr
    assert not out.exists()
