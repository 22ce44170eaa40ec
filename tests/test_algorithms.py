"""sb3-contrib's algorithms through train.py: a tiny run each, resumed, loaded and evaluated
(a recurrent policy's LSTM state carried through the evaluation's rollout)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from capsule_env.agents.learning import train  # noqa: E402
from capsule_env.agents.learning.algorithms import ALGORITHMS, ON_POLICY, algorithm_class  # noqa: E402
from capsule_env.agents.learning.sb3_policy import SB3Policy  # noqa: E402
from test_train import edited_yml  # noqa: E402

from capsule_env.evaluation.episodes import run_episodes  # noqa: E402

pytestmark = pytest.mark.rl
ROOT = Path(__file__).resolve().parents[1]
SMALL = {
    "tqc": {"learning_starts": 100, "batch_size": 32},
    "crossq": {"learning_starts": 100, "batch_size": 32},
    "recurrentppo": {"n_steps": 64, "batch_size": 64, "n_epochs": 1},
}


@pytest.mark.parametrize("algo", sorted(SMALL))
def test_tiny_run_resume_load_and_evaluate(algo, tmp_path):
    yml = edited_yml(algo, tmp_path, **SMALL[algo])
    argv = ["--algo", algo, "--hyperparams", str(yml), "--num-envs", "2", "--total-timesteps",
            "256", "--eval-freq", "0", "--checkpoint-freq", "128", "--threads", "1",
            "--output-dir", str(tmp_path / "run"), "--name", f"tiny-{algo}",
            "--eval-episodes", "1", "--eval-episode-length", "0.5"]  # fmt: skip
    summary = train.train(train.parse_args(argv))
    assert summary["num_timesteps"] == 256
    at = argv.index("--total-timesteps") + 1
    resumed = train.train(
        train.parse_args([*argv[:at], "384", *argv[at + 1 :], "--resume", "auto"])
    )
    assert resumed["num_timesteps"] == 384
    assert isinstance(resumed["model"], algorithm_class(algo))
    policy = SB3Policy.load(tmp_path / "run" / "final_model.zip")
    assert policy.meta["algo"] == algo
    rollout = run_episodes(policy, dict(policy.env_kwargs), seeds=[1, 2], episode_length_s=0.5)
    forces = rollout.signals["damper_force_n"]
    assert forces.shape == (2, 100) and np.all(np.isfinite(forces)) and np.any(forces != 0)


def test_every_algorithm_has_a_hyperparameter_file_and_a_class():
    for name in ALGORITHMS:
        assert (ROOT / "hyperparams" / f"{name}.yml").is_file()
        assert callable(algorithm_class(name).load)
    assert set(ON_POLICY) == {n for n in ALGORITHMS if "ppo" in n}
    with pytest.raises(ValueError, match="algo must be one of ppo, sac, td3, tqc"):
        algorithm_class("dqn")
