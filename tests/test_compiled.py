"""``torch.compile`` of PPO's update (agents/learning/compiled.py, ``train.py --compile``): it trains as
the eager update does, within float32 rounding, and leaves the saved files as they were."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import NO_SB3, NO_YAML

pytest.importorskip("stable_baselines3", reason=NO_SB3)
pytest.importorskip("yaml", reason=NO_YAML)

import torch  # noqa: E402
from capsule_env.agents.learning import train  # noqa: E402
from capsule_env.agents.learning.compiled import check_compile, compile_update, is_compiled  # noqa: E402
from capsule_env.agents.learning.run_args import continue_command  # noqa: E402
from capsule_env.agents.learning.sb3_policy import SB3Policy  # noqa: E402
from test_train import edited_yml, fast_args  # noqa: E402

pytestmark = pytest.mark.rl

ROOT = Path(__file__).resolve().parent.parent


def _ppo_parameters(compiled: bool) -> tuple[dict, dict]:
    """PPO's parameters before and after two updates (4 vehicles x 80 steps = 320 samples in
    minibatches of 96: three full ones and a last one of 32, so two graph shapes; 2 epochs: 16
    gradient steps) on the ride task, seed 3, eager or with the update compiled."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    env = VecNormalize(CapsuleSuspensionSB3VecEnv(4, setting="hils", action_mode="force",
                                                  observation="measured"))  # fmt: skip
    model = PPO("MlpPolicy", env, n_steps=80, batch_size=96, n_epochs=2, learning_rate=1e-3,
                seed=3, device="cpu", policy_kwargs={"net_arch": [64, 64], "log_std_init": -1.0})  # fmt: skip
    start = {k: v.clone() for k, v in model.policy.state_dict().items()}
    if compiled:
        compile_update(model)
        assert is_compiled(model)
    model.learn(640)
    env.close()
    return start, {k: v.clone() for k, v in model.policy.state_dict().items()}


def test_compiled_update_trains_as_the_eager_one():
    from torch._dynamo.utils import counters

    torch.set_num_threads(1)
    start, eager = _ppo_parameters(False)
    _, eager_again = _ppo_parameters(False)
    torch._dynamo.reset()  # a graph cached by an earlier test would not count again
    graphs_before = counters["stats"]["unique_graphs"]
    _, compiled = _ppo_parameters(True)
    # dynamo compiled the update: one graph per minibatch shape (96 and the last one's 32)
    assert counters["stats"]["unique_graphs"] >= graphs_before + 1
    for name, value in eager.items():
        # the reference is exact: the same seed, eager twice, gives the same bits
        torch.testing.assert_close(eager_again[name], value, rtol=0, atol=0)
        change = (value - start[name]).abs().max().item()
        difference = (compiled[name] - value).abs().max().item()
        # Fused kernels sum in another order: float32 rounding (~1e-7 relative per operation)
        # carried through 16 Adam steps (eps 1e-5 keeps a near-zero gradient from turning a
        # rounding difference into a full step). Measured: at most 3e-8 (6e-8 with an uneven
        # last minibatch), against updates of 3e-3..2e-2; the bound 1e-5 is 150 x that and
        # still 300 x below the smallest update, so a wrong gradient (an update of another
        # size or sign) fails it.
        assert difference <= 1e-5, (name, difference)
        assert change >= 100 * 1e-5, (name, change)  # every tensor did learn


def test_train_py_compile_option_saves_resumes_and_loads(tmp_path):
    yml = edited_yml("ppo", tmp_path, n_steps=256, batch_size=256, n_epochs=2)
    argv = fast_args(yml, tmp_path / "run", "--total-timesteps", "1024", "--eval-freq", "0",
                     "--compile")  # fmt: skip
    args = train.parse_args(argv)
    from torch._dynamo.utils import counters

    torch._dynamo.reset()
    graphs_before = counters["stats"]["unique_graphs"]
    summary = train.train(args)
    assert is_compiled(summary["model"])
    assert counters["stats"]["unique_graphs"] > graphs_before  # the compiled update ran
    meta = json.loads((tmp_path / "run" / "final_model.json").read_text())
    assert meta["compiled_update"] is True
    assert "--compile" in continue_command(args, tmp_path / "run")
    # the saved policy loads and acts without torch.compile, as its own parameters say
    policy = SB3Policy.load(tmp_path / "run" / "final_model.zip")
    assert not is_compiled(policy.model)
    for name, value in summary["model"].policy.state_dict().items():
        torch.testing.assert_close(policy.model.policy.state_dict()[name], value, rtol=0, atol=0)
    action, _ = policy.predict(np.zeros((2, policy.obs_rms.mean.shape[0]), dtype=np.float32))
    assert action.shape == (2, 1) and np.all(np.abs(action) <= 1)
    # --compile is each process's choice: a resume compiles again only when asked
    resumed = train.train(train.parse_args([*argv[:-1], "--total-timesteps", "2048",
                                            "--resume", "auto", "--compile"]))  # fmt: skip
    assert resumed["num_timesteps"] == 2048 and is_compiled(resumed["model"])
    plain = train.train(train.parse_args([*argv[:-1], "--total-timesteps", "3072",
                                          "--resume", "auto"]))  # fmt: skip
    assert plain["num_timesteps"] == 3072 and not is_compiled(plain["model"])


def test_a_copy_of_a_compiled_policy_uses_its_own_parameters():
    import copy

    from stable_baselines3 import PPO

    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    env = CapsuleSuspensionSB3VecEnv(2, setting="hils", action_mode="force", observation="measured")
    model = PPO("MlpPolicy", env, n_steps=8, batch_size=16, device="cpu", seed=0)
    compile_update(model)
    twin = copy.deepcopy(model.policy)
    with torch.no_grad():
        for parameter in twin.parameters():
            parameter.add_(0.1)
    obs = torch.randn(5, env.observation_space.shape[0], generator=torch.Generator().manual_seed(0))
    actions = torch.zeros(5, 1)
    mine = twin.evaluate_actions(obs, actions)[0]
    expected = type(twin).evaluate_actions(twin, obs, actions)[0]  # eager, the copy's parameters
    original = type(model.policy).evaluate_actions(model.policy, obs, actions)[0]
    torch.testing.assert_close(mine, expected, rtol=1e-5, atol=1e-6)  # float32 rounding
    assert (mine - original).abs().max() > 1e-2  # not the original's parameters
    env.close()


def test_compile_without_a_cpp_compiler_is_refused_before_training(tmp_path, monkeypatch):
    from torch._inductor import config

    monkeypatch.setattr(config.cpp, "cxx", (None, str(tmp_path / "no-such-g++")))
    with pytest.raises(ValueError, match="--compile needs a C[+][+] compiler"):
        check_compile("ppo", True)


@pytest.mark.parametrize("algo", ["sac", "td3", "tqc", "crossq", "recurrentppo"])
def test_compile_is_refused_for_other_algorithms(algo):
    with pytest.raises(ValueError, match=f"--compile serves ppo only.*not {algo}"):
        check_compile(algo, True)
    check_compile(algo, False)  # without --compile, nothing to refuse


def test_train_py_compile_with_sac_is_one_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "train.py", "--algo", "sac", "--compile", "--output-dir",
         str(tmp_path), "--total-timesteps", "10", "--no-progress"],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode != 0
    assert result.stderr.strip().splitlines() == [
        "train.py: error: --compile serves ppo only (its update's evaluate_actions), not sac"
    ]
    assert not any(tmp_path.iterdir())  # refused before any folder was made
