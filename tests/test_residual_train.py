"""train.py --residual: a residual PPO run on a tiny budget, saved and loaded as the residual of
its law; its composition checked against the law and the network computed separately."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import NO_SB3, NO_YAML

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)

from capsule_env.agents.controllers.classical import make_controller  # noqa: E402
from capsule_env.agents.learning import train  # noqa: E402
from capsule_env.agents.learning.residual import ResidualPolicy, zero_last_layer  # noqa: E402
from capsule_env.agents.learning.sb3_policy import SB3Policy, load_policy  # noqa: E402

from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv  # noqa: E402

pytestmark = pytest.mark.rl

ROOT = Path(__file__).resolve().parent.parent
LAW = "lqr-clipped-biexp-meas"
SCALE = 0.3


@pytest.fixture(scope="module")
def residual_run(tmp_path_factory):
    """Two PPO rollouts of 4 vehicles x 256 steps on the ride task, residual of the LQR."""
    folder = tmp_path_factory.mktemp("residual")
    yml = folder / "ppo.yml"
    text = (ROOT / "hyperparams" / "ppo.yml").read_text()
    for key, value in (("n_steps", 256), ("batch_size", 256), ("n_epochs", 2)):
        text, count = re.subn(rf"^  {key}: \d+", f"  {key}: {value}", text, flags=re.M)
        assert count == 1, key
    yml.write_text(text)
    argv = ["--num-envs", "4", "--eval-episodes", "2", "--eval-episode-length", "1",
            "--no-progress", "--hyperparams", str(yml), "--total-timesteps", "2048",
            "--eval-freq", "1024", "--residual", LAW, "--residual-scale", str(SCALE),
            "--output-dir", str(folder / "run")]  # fmt: skip
    starts: list[float] = []

    class FirstAction:  # the model's deterministic action before any update
        def __new__(cls):
            from stable_baselines3.common.callbacks import BaseCallback

            class _Cb(BaseCallback):
                def _on_training_start(self) -> None:
                    obs = self.model._last_obs  # normalised: what the first step acts on
                    action, _ = self.model.predict(obs, deterministic=True)
                    starts.extend(np.ravel(action).tolist())

                def _on_step(self) -> bool:
                    return True

            return _Cb()

    summary = train.train(train.parse_args(argv), extra_callbacks=[FirstAction()])
    return folder / "run", summary, starts


def test_residual_run_trains_two_rollouts_from_a_zero_correction(residual_run):
    out, summary, starts = residual_run
    assert summary["num_timesteps"] == 2048 and not summary["interrupted"]
    assert starts == [0.0] * 4  # zero last layer: the first actions are the law's own
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    assert [json.loads(line)["num_timesteps"] for line in lines] == [1024, 2048]
    meta = json.loads((out / "best_model.json").read_text())
    assert meta["residual"] == {"law": LAW, "scale": SCALE}
    assert meta["args"]["residual"] == LAW


def _episode_observations(env_kwargs: dict, steps: int) -> np.ndarray:
    env = CapsuleSuspensionEnv(**{**env_kwargs, "setting": "hils", "guideway_seed": 3})
    obs, _ = env.reset(seed=11)
    law = make_controller(LAW)
    out = [obs]
    for _ in range(steps - 1):
        action, _ = law.predict(obs[None], deterministic=True)
        obs, *_ = env.step(action[0])
        out.append(obs)
    return np.asarray(out, dtype=np.float32)


def test_saved_residual_policy_is_law_plus_scaled_network(residual_run):
    out = residual_run[0]
    policy = load_policy(out / "best_model.zip")
    assert isinstance(policy, ResidualPolicy) and policy.law.name == LAW
    assert policy.scale == SCALE and policy.name.startswith("ppo-seed0")
    obs = _episode_observations(policy.env_kwargs, 40)
    net = SB3Policy.load(out / "best_model.zip")  # the network alone, its own statistics
    law = make_controller(LAW)  # a fresh instance: the law's own requests
    start = np.zeros(1, dtype=bool)
    for k, o in enumerate(obs):
        start[0] = k == 0
        got, _ = policy.predict(o[None], episode_start=start.copy())
        base, _ = law.predict(o[None], episode_start=start.copy(), deterministic=True)
        correction, _ = net.predict(o[None])
        want = np.clip(base[0, 0] + SCALE * correction[0, 0], -1.0, 1.0)
        assert got[0, 0] == pytest.approx(want, abs=1e-6)
    # trained: the correction is not zero everywhere
    assert np.abs(np.ravel(net.predict(obs)[0])).max() > 0.0


def test_saved_residual_with_zeroed_last_layer_acts_as_the_law(residual_run):
    policy = load_policy(residual_run[0] / "best_model.zip")
    zero_last_layer(policy.policy.model)
    obs = _episode_observations(policy.env_kwargs, 40)
    law = make_controller(LAW)
    policy.reset()
    start = np.zeros(1, dtype=bool)
    for k, o in enumerate(obs):
        start[0] = k == 0
        got, _ = policy.predict(o[None], episode_start=start.copy())
        want, _ = law.predict(o[None], episode_start=start.copy(), deterministic=True)
        assert got[0, 0] == np.float32(want[0, 0])


def test_evaluate_cli_loads_the_residual_policy(residual_run):
    out = residual_run[0]
    proc = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), "--policy", str(out / "best_model.zip"),
         "--controllers", "passive", "--no-shipped-policy", "--episodes", "1",
         "--episode-length", "1", "--json", str(out / "eval.json")],
        capture_output=True, text=True, cwd=ROOT)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    rows = json.loads((out / "eval.json").read_text())["settings"]
    names = {name for block in rows.values() for name in block["controllers"]}
    assert "ppo-seed0" in names


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--residual", "no-such-law"], "--residual must name a classical controller"),
        (["--residual", LAW, "--residual-scale", "0"], "--residual-scale must be in (0, 2]"),
        (["--residual", "lqr-clipped-biexp"], "needs the env option observation='full_state'"),
    ],
)
def test_bad_residual_arguments_are_one_line(argv, needle, tmp_path):
    proc = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *argv, "--output-dir", str(tmp_path / "r"),
         "--total-timesteps", "1"], capture_output=True, text=True, cwd=ROOT)  # fmt: skip
    assert proc.returncode != 0
    assert needle in proc.stderr and "Traceback" not in proc.stderr
