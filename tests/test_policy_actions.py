"""experiments/policy_actions.py: its statistics against hand-made controllers whose actions are
known (a constant request, a request alternating between the bounds), its Wk against
evaluation's own on the same episodes, the entropy coefficient of a SAC-family model, and its
bad input (one line, exit 2)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import load_script

ROOT = Path(__file__).resolve().parent.parent
RIDE = {"setting": "hils", "observation": "measured", "action_mode": "force", "guideway_seed": 7}


@pytest.fixture(scope="module")
def pa():
    return load_script("experiments/policy_actions.py")


class Constant:
    """Asks for ``value`` of the force range at every step."""

    env_kwargs: dict = {}

    def __init__(self, value: float) -> None:
        self.value = value

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.full((len(obs), 1), self.value, dtype=np.float32), state


class Alternating(Constant):
    """+1, -1, +1, ... of the force range, step after step."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.value = -self.value
        return np.full((len(obs), 1), self.value, dtype=np.float32), state


def test_a_constant_request_has_its_value_for_mean_and_no_spread(pa):
    row = pa.action_statistics(Constant(0.3), RIDE, [5000, 5001], episode_length_s=0.5)
    assert row["mean"] == pytest.approx(0.3, abs=1e-7)  # float32 actions
    assert row["std"] == pytest.approx(0.0, abs=1e-7)
    assert row["share_at_bound"] == 0.0 and row["terminated_episodes"] == 0
    assert row["samples"] == 2 * 100  # two episodes of 0.5 s at the 5 ms control step


def test_a_request_alternating_between_the_bounds(pa):
    row = pa.action_statistics(Alternating(-1.0), RIDE, [5000], episode_length_s=0.5)
    # 100 steps: +1 and -1 fifty times each
    assert row["mean"] == pytest.approx(0.0, abs=1e-12)
    assert row["std"] == pytest.approx(1.0, abs=1e-12)
    assert row["share_at_bound"] == 1.0


class Squares(Constant):
    """Episode k asks for k**2 / 10 of the force range at every step."""

    def __init__(self) -> None:
        super().__init__(0.0)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return (np.arange(len(obs), dtype=np.float32)[:, None] ** 2) / 10, state


def test_an_episode_that_hits_the_bump_stop_is_left_out(pa):
    # Episodes 5000..5003 with these requests reach strokes of 11.4, 12.5, 11.6 and 10.8 mm in
    # 2 s (no limit): a 12 mm bump stop ends episode 1 only (margins of 0.4 mm and more).
    kwargs = {**RIDE, "stroke_limit_m": 0.012}
    row = pa.action_statistics(Squares(), kwargs, [5000, 5001, 5002, 5003], episode_length_s=2.0)
    assert row["terminated_episodes"] == 1
    kept = np.array([0.0, 0.4, 0.9])  # episodes 0, 2 and 3; all four would give a mean of 0.35
    assert row["mean"] == pytest.approx(kept.mean(), abs=1e-7)
    assert row["std"] == pytest.approx(kept.std(), abs=1e-7)
    assert row["samples"] == 3 * 400


@pytest.mark.parametrize("value, share", [(0.96, 1.0), (0.94, 0.0), (-0.96, 1.0)])
def test_the_bound_is_095(pa, value, share):
    row = pa.action_statistics(Constant(value), RIDE, [5000], episode_length_s=0.1)
    assert row["share_at_bound"] == share and row["action_mode"] == "force"


def test_its_wk_is_evaluations_on_the_same_episodes(pa):
    from capsule_env.agents import classical_controllers

    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    law = classical_controllers()["lqr-clipped-biexp-meas"]
    kwargs = {**RIDE, **law.env_kwargs}
    row = pa.action_statistics(law, kwargs, [5000, 5001], episode_length_s=1.0)
    direct = episode_metrics(run_episodes(law, kwargs, seeds=[5000, 5001], episode_length_s=1.0),
                             None)["wk_rms_body_acc_m_s2"]  # fmt: skip
    assert row["wk_rms_body_acc_m_s2"] == direct  # the same run: recording changes nothing
    assert 0.0 < row["std"] < 1.0


def test_entropy_coefficient_of_a_sac_model(pa):
    torch = pytest.importorskip("torch")
    pytest.importorskip("stable_baselines3")
    from capsule_env.agents.learning.sb3_policy import SB3Policy
    from stable_baselines3 import PPO, SAC

    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    env = CapsuleSuspensionSB3VecEnv(1, setting="hils", action_mode="force", observation="measured")
    sac = SAC("MlpPolicy", env, ent_coef="auto_0.137", device="cpu", seed=0)
    assert pa.entropy_coefficient(SB3Policy.from_model(sac, None)) == pytest.approx(0.137, rel=1e-6)
    with torch.no_grad():
        sac.log_ent_coef.fill_(math.log(0.01))  # what training moves
    assert pa.entropy_coefficient(SB3Policy.from_model(sac, None)) == pytest.approx(0.01, rel=1e-6)
    ppo = PPO("MlpPolicy", env, n_steps=8, batch_size=8, device="cpu")
    assert pa.entropy_coefficient(SB3Policy.from_model(ppo, None)) is None
    assert pa.entropy_coefficient(Constant(0.0)) is None
    # a policy whose observations are not the env's is refused, naming both shapes
    with pytest.raises(ValueError, match=r"shape \(9,\), the task's env gives \(41,\)"):
        pa.check_observation("p", SB3Policy.from_model(ppo, None),
                             {"setting": "hils", "observation": "measured", "preview_points": 32})  # fmt: skip
    env.close()


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--law", "nope"], "--law 'nope'"),
        (["--policy", "/nonexistent.zip"], "--policy /nonexistent.zip"),
        (["--task", "Foo-v0", "--law", "passive"], "--task"),
        (["--episodes", "0", "--law", "passive"], "--episodes must be in [1, 100]"),
        (["--first-seed", "-1", "--law", "passive"], "--first-seed must be in [0,"),
        ([], "give at least one --policy or --law"),
    ],
)
def test_bad_input_is_one_line(argv, words):
    result = subprocess.run([sys.executable, "experiments/policy_actions.py", *argv], cwd=ROOT,
                            capture_output=True, text=True, timeout=120)  # fmt: skip
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in result.stderr


def test_json_records_the_command_and_every_controller(pa, tmp_path):
    out = tmp_path / "a.json"
    assert pa.main(["--law", "passive", "--law", "skyhook-cont-biexp", "--episodes", "1",
                    "--json", str(out)]) == 0  # fmt: skip
    data = json.loads(out.read_text())
    assert list(data["results"]) == ["passive", "skyhook-cont-biexp"]
    assert data["seeds"] == [5000] and data["guideway_seed"] == 7
    assert data["command"].startswith("python experiments/policy_actions.py --law passive")
