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


def test_its_wk_is_evaluations_on_the_same_episodes(pa):
    from capsule_env.agents import classical_controllers

    from capsule_env.evaluation import episode_metrics, run_episodes

    law = classical_controllers()["lqr-clipped-biexp-meas"]
    kwargs = {**RIDE, **law.env_kwargs}
    row = pa.action_statistics(law, kwargs, [5000, 5001], episode_length_s=1.0)
    direct = episode_metrics(run_episodes(law, kwargs, seeds=[5000, 5001], episode_length_s=1.0),
                             None)["wk_rms_body_acc_m_s2"]  # fmt: skip
    assert row["wk_rms_body_acc_m_s2"] == direct  # the same run: recording changes nothing
    assert 0.0 < row["std"] < 1.0


def test_entropy_coefficient_of_a_sac_family_model(pa):
    torch = pytest.importorskip("torch")

    class Model:
        log_ent_coef = torch.tensor([math.log(0.137)])

    class Policy:
        model = Model()

    assert pa.entropy_coefficient(Policy()) == pytest.approx(0.137, rel=1e-6)
    assert pa.entropy_coefficient(Constant(0.0)) is None


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--law", "nope"], "--law 'nope'"),
        (["--policy", "/nonexistent.zip"], "--policy /nonexistent.zip"),
        (["--task", "Foo-v0", "--law", "passive"], "--task"),
        (["--episodes", "0", "--law", "passive"], "--episodes must be in [1, 100]"),
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
