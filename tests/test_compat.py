"""Works unmodified with RL code its authors did not write (issue 17, section 1).

- Gymnasium 1.0 (no ``AutoresetMode``): the package imports and the vector env runs.
- An unknown keyword is Python's ``TypeError`` (TorchRL's ``GymEnv`` retries without
  ``frameskip`` on it) and this package's ``ValueError``.
- ``render_fps`` is the control rate: ``RecordVideo`` writes real-time videos.
- Gymnasium's env checkers, TorchRL's ``GymEnv`` / ``GymWrapper`` with ``check_env_specs``.

Tests of optional libraries (moviepy, TorchRL, stable-baselines3) are skipped, with the
reason, when the library is absent. The autoreset modes are in ``test_autoreset.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import capsule_env  # noqa: F401  (registers the env)
from capsule_env.engine.config import EnvConfig, UnexpectedArgumentError
from capsule_env.envs import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv
from capsule_env.envs._compat import GYMNASIUM_HAS_AUTORESET_MODE

from conftest import ENV_ID, NO_SB3

REPO = Path(__file__).resolve().parents[1]


def _needs_torchrl() -> None:
    pytest.importorskip(
        "torchrl", reason="torchrl is not installed (optional: pip install torchrl)"
    )
    if not GYMNASIUM_HAS_AUTORESET_MODE:
        pytest.skip("TorchRL refuses gymnasium 1.0 (its own GYMNASIUM_1_ERROR); use gymnasium>=1.1")


# ------------------------------------------------------------------ gymnasium lower bound
def test_declared_gymnasium_lower_bound_is_what_the_code_supports():
    text = (REPO / "pyproject.toml").read_text()
    assert '"gymnasium>=1.0"' in text  # the compat shim below keeps 1.0 importable


def test_imports_and_runs_without_autoreset_mode_as_on_gymnasium_1_0():
    # Gymnasium 1.0 has no gymnasium.vector.AutoresetMode: remove it, then import the package
    # in a fresh interpreter and run every mode of the native vector env.
    code = """
import gymnasium.vector as gv
if hasattr(gv, "AutoresetMode"):
    del gv.AutoresetMode
import numpy as np, gymnasium as gym, capsule_env
from capsule_env.envs._compat import GYMNASIUM_HAS_AUTORESET_MODE, AutoresetMode
assert not GYMNASIUM_HAS_AUTORESET_MODE
for mode in ("NextStep", "SameStep", "Disabled"):
    vec = gym.make_vec("CapsuleSuspension-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       autoreset_mode=mode, episode_length_s=0.02)
    vec.reset(seed=0)
    for _ in range(4):
        vec.step(np.zeros((2, 1)))
    print(vec.autoreset_mode.value, vec.metadata["autoreset_mode"] is vec.autoreset_mode)
env = gym.make("CapsuleSuspension-v0"); env.reset(seed=0); env.step(np.zeros(1, np.float32))
"""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["NextStep", "True", "SameStep", "True", "Disabled", "True"]


# ---------------------------------------------------------------------- unknown keywords
def _python_message() -> str:
    def f() -> None:
        pass

    try:
        f(frameskip=4)  # type: ignore[call-arg]
    except TypeError as err:
        return str(err).split("() ", 1)[1]  # "got an unexpected keyword argument 'frameskip'"
    raise AssertionError("unreachable")


@pytest.mark.parametrize(
    "make",
    [
        lambda: gym.make(ENV_ID, frameskip=4),
        lambda: gym.make(f"capsule_env:{ENV_ID}", frameskip=4),
        lambda: CapsuleSuspensionEnv(frameskip=4),
        lambda: CapsuleSuspensionVectorEnv(num_envs=2, frameskip=4),
        lambda: gym.make_vec(
            ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", frameskip=4
        ),  # fmt: skip
        lambda: EnvConfig.from_kwargs(frameskip=4),
    ],
    ids=["make", "make-module-prefix", "env", "vector-env", "make_vec", "config"],
)
def test_unknown_keyword_is_a_type_error_and_a_value_error(make):
    assert issubclass(UnexpectedArgumentError, TypeError)
    assert issubclass(UnexpectedArgumentError, ValueError)
    wording = _python_message()
    with pytest.raises(TypeError, match=wording) as as_type:
        make()
    with pytest.raises(ValueError, match=wording) as as_value:
        make()
    for err in (as_type.value, as_value.value):
        assert "accepted:" in str(err) and "action_mode" in str(err)


def test_unknown_keyword_lists_the_env_s_own_arguments_too():
    with pytest.raises(TypeError, match=r"CapsuleSuspensionEnv.__init__\(\).*render_mode"):
        CapsuleSuspensionEnv(frameskip=4)
    with pytest.raises(TypeError, match=r"VectorEnv.__init__\(\).*autoreset_mode.*num_envs"):
        CapsuleSuspensionVectorEnv(frameskip=4)
    with pytest.raises(ValueError, match="action_mode"):  # other bad values stay ValueErrors
        CapsuleSuspensionEnv(action_mode="torque")


def test_sb3_vec_env_unknown_keyword():
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    with pytest.raises(TypeError, match="unexpected keyword argument 'frameskip'"):
        CapsuleSuspensionSB3VecEnv(2, frameskip=4)


# ------------------------------------------------------------------------ real-time video
@pytest.mark.parametrize("rate", [200.0, 50.0, 125.0])
def test_render_fps_is_one_frame_per_control_step(rate):
    # A video that shows one frame per step is real time when fps x step interval = 1.
    single = gym.make(ENV_ID, render_mode="rgb_array", control_rate_hz=rate)
    vec = CapsuleSuspensionVectorEnv(num_envs=2, control_rate_hz=rate)
    for env in (single, single.unwrapped, vec):
        assert env.metadata["render_fps"] * (1.0 / rate) == pytest.approx(1.0, abs=1e-12)
    assert CapsuleSuspensionEnv.metadata["render_fps"] == 200  # the class default: 200 Hz


def test_sb3_vec_env_render_fps_is_the_control_rate():
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    for rate in (200.0, 50.0):
        assert CapsuleSuspensionSB3VecEnv(1, control_rate_hz=rate).metadata["render_fps"] == rate


@pytest.mark.parametrize("rate", [200.0, 50.0])
def test_record_video_plays_in_real_time(tmp_path, rate):
    pytest.importorskip("moviepy", reason="moviepy is not installed (RecordVideo needs it)")
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="imageio-ffmpeg is absent")
    from gymnasium.wrappers import RecordVideo

    seconds = 0.5
    env = gym.make(ENV_ID, render_mode="rgb_array", control_rate_hz=rate, episode_length_s=seconds)
    folder = tmp_path / "videos"
    env = RecordVideo(env, str(folder), episode_trigger=lambda _: True, disable_logger=True)
    env.reset(seed=0)
    steps, done = 0, False
    while not done:
        *_, terminated, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
        done, steps = terminated or truncated, steps + 1
    env.close()
    assert steps == round(seconds * rate)
    (video,) = folder.glob("*.mp4")
    frames, duration = imageio_ffmpeg.count_frames_and_secs(str(video))
    assert frames == steps + 1  # the reset frame and one per step
    # real time: the video lasts as long as the episode's simulated time (one frame's slack)
    assert duration == pytest.approx(seconds, abs=1.5 / rate)


# -------------------------------------------------------------- Gymnasium's env checkers
def test_gymnasium_env_checkers_pass_without_warnings():
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make(ENV_ID, render_mode="rgb_array", disable_env_checker=False,
                       episode_length_s=0.05)  # fmt: skip
        wrappers = []
        inner = env
        while isinstance(inner, gym.Wrapper):
            wrappers.append(type(inner).__name__)
            inner = inner.env
        assert "PassiveEnvChecker" in wrappers
        for episode in range(2):  # the passive checker watches the first reset, step, render
            env.reset(seed=episode)
            done = False
            while not done:
                obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
                assert env.observation_space.contains(obs)
                done = terminated or truncated
            assert env.render().shape[2] == 3
        check_env(env.unwrapped, skip_render_check=False)
        hils = gym.make(ENV_ID, render_mode="rgb_array", setting="hils")
        check_env(hils.unwrapped, skip_render_check=False)


# --------------------------------------------------------------------------------- TorchRL
def test_torchrl_gym_env_passes_check_env_specs():
    _needs_torchrl()
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv(f"capsule_env:{ENV_ID}", episode_length_s=0.05)  # passes frameskip= first
    check_env_specs(env)
    td = env.rollout(25, break_when_any_done=False)
    assert td["next", "done"].sum().item() == 2  # 10-step episodes, reset by TorchRL
    env.close()


@pytest.mark.parametrize("mode", ["SameStep", "Disabled"])
def test_torchrl_gym_wrapper_over_the_native_vector_env(mode):
    _needs_torchrl()
    import torch
    from torchrl.envs import GymWrapper
    from torchrl.envs.utils import check_env_specs

    # A deterministic guideway and no noise: every episode is the same, whatever the seeds.
    kw = dict(guideway="sine", episode_length_s=0.05, num_envs=2)
    vec = gym.make_vec(ENV_ID, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kw)
    env = GymWrapper(vec)
    check_env_specs(env)

    def policy(td):
        return td.set("action", torch.full((2, 1), 0.25))

    td = env.rollout(25, policy=policy, break_when_any_done=False)
    # The same run driven directly: root observations and next observations per step.
    ref = CapsuleSuspensionVectorEnv(autoreset_mode="SameStep", **kw)
    obs, _ = ref.reset(seed=0)
    root, after = [], []
    for _ in range(25):
        root.append(obs)
        obs, _, term, trunc, info = ref.step(np.full((2, 1), 0.25))
        after.append(np.stack(info["final_obs"]) if (term | trunc).all() else obs)
    done = td["next", "done"].squeeze(-1).numpy()  # (envs, steps)
    assert done.sum(axis=1).tolist() == [2, 2] and done[:, 9].all() and done[:, 19].all()
    np.testing.assert_array_equal(td["observation"].numpy(), np.stack(root, axis=1))
    np.testing.assert_array_equal(td["next", "observation"].numpy(), np.stack(after, axis=1))
    env.close()
