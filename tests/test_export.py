"""Issue 44, items 1-2: exported policies (ONNX, C99, the contract) act as the policy does.

The independent fact: SB3's own deterministic action, ``model.predict(normalised obs,
deterministic=True)`` clipped to [-1, 1] (``SB3Policy.predict``), computed by torch from the
saved model and the pickled ``VecNormalize``. The ONNX graph (run by onnxruntime) and the C
file (compiled here by the system's C compiler with strict C99 flags, called through ctypes) are
written by the export from the same files, and must agree with it to 1e-5 on observations of
real rollouts of the policy (its own actions driving the env). The C forms of the classical
laws are checked against the Python laws the same way.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import NO_SB3, residual_copy

pytest.importorskip("stable_baselines3", reason=NO_SB3)
EXPORT_EXTRA = "optional, in the export extra: pip install 'capsule-env[export]'"
ort = pytest.importorskip("onnxruntime", reason=f"onnxruntime is not installed ({EXPORT_EXTRA})")
pytest.importorskip("onnxscript", reason=f"onnxscript is not installed ({EXPORT_EXTRA})")

from capsule_env.agents.learning.sb3_policy import (  # noqa: E402
    PRETRAINED_DIR,
    SB3Policy,
    load_policy,
    missing_solver,
)

from capsule_env.envs import CapsuleSuspensionVectorEnv  # noqa: E402
from capsule_env.envs.declared_vector import DeclaredVectorEnv  # noqa: E402
from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.__main__ import main  # noqa: E402
from capsule_env.export.c_build import CPolicy, build_shared, c_compiler  # noqa: E402

pytestmark = pytest.mark.rl
ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p.name[: -len(".zip")] for p in PRETRAINED_DIR.glob("*.zip"))
TOLERANCE = 1e-5
NO_COMPILER = "no C compiler on this machine (cc, gcc, clang or $CC): the C export is not built"


def rollout_obs(policy, env_kwargs: dict, vehicles: int = 4, steps: int = 200,
                episode_length_s: float = 2.0) -> np.ndarray:  # fmt: skip
    """The observations of ``steps`` control steps of ``vehicles`` episodes that ``policy``
    drives (its deterministic actions), guideway bank 3, seeds 40.. (rows: every step).
    ``episode_start`` is SB3's: True where the observation is a new episode's first. The envs
    autoreset on the step after an episode's end (NEXT_STEP): the observation returned with
    ``terminated | truncated`` is the old episode's last, the next step's is the new one's first."""
    make = DeclaredVectorEnv if "vehicle" in env_kwargs else CapsuleSuspensionVectorEnv
    env = make(num_envs=vehicles, guideway_seed=3, episode_length_s=episode_length_s, **env_kwargs)
    obs, _ = env.reset(seed=list(range(40, 40 + vehicles)))
    policy.reset() if hasattr(policy, "reset") else None
    start, ended, rows = np.ones(vehicles, dtype=bool), np.zeros(vehicles, dtype=bool), []
    for _ in range(steps):
        rows.append(obs.copy())
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        obs, _, terminated, truncated, _ = env.step(np.asarray(action, np.float32))
        start, ended = ended, terminated | truncated
    env.close()
    return np.concatenate(rows).astype(np.float32)


def test_the_rollout_flags_each_episode_first_observation():
    """Episodes of 10 control steps (50 ms at 5 ms): the episode ends with the 10th step, the
    11th step only resets (NEXT_STEP), so the episodes' first observations are rows 0, 11, 22."""

    class Recorder:
        def __init__(self) -> None:
            self.starts: list[bool] = []

        def predict(self, obs, episode_start=None, deterministic=True):
            self.starts.append(bool(episode_start[0]))
            return np.zeros((obs.shape[0], 1), np.float32), None

    recorder = Recorder()
    rollout_obs(recorder, {"setting": "hils"}, vehicles=1, steps=30, episode_length_s=0.05)
    assert np.flatnonzero(recorder.starts).tolist() == [0, 11, 22]


def network_of(policy):
    """The SB3 policy whose action the artifacts compute (a residual's network)."""
    return getattr(policy, "policy", policy)


def c_policy(files: dict[str, Path], name: str, obs_size: int, folder: Path,
             action_size: int = 1) -> CPolicy:  # fmt: skip
    if c_compiler() is None:
        pytest.skip(NO_COMPILER)
    return CPolicy(build_shared(files[f"{name}.c"], folder), obs_size, action_size)


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, dict[str, Path]]:
    """Every shipped policy exported (onnx and c) into one folder."""
    out = tmp_path_factory.mktemp("exported")
    return {name: export_policy(name, out) for name in SHIPPED}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_policy_exports_act_as_the_policy(name, exported, tmp_path):
    path = PRETRAINED_DIR / f"{name}.zip"
    if missing_solver(path):
        pytest.skip(f"{name}'s law needs DAQP for its rollouts (pip install 'capsule-env[mpc]')")
    policy = load_policy(path)
    meta = json.loads((PRETRAINED_DIR / f"{name}.json").read_text())
    obs = rollout_obs(policy, meta["env_kwargs"])
    expected, _ = network_of(policy).predict(obs, deterministic=True)
    # the comparison is not vacuous: the actions spread, most are not at the clip
    assert np.std(expected) > 0.05 and np.mean(np.abs(expected) < 0.999) > 0.5
    files = exported[name]
    onnx = ort.InferenceSession(str(files[f"{name}.onnx"]), providers=["CPUExecutionProvider"])
    got_onnx = onnx.run(None, {"obs": obs})[0]
    assert got_onnx.shape == expected.shape
    np.testing.assert_allclose(got_onnx, expected, rtol=0, atol=TOLERANCE)
    # one action per damper slot: 2 for the half-car's policy
    got_c = c_policy(files, name, obs.shape[1], tmp_path, expected.shape[1]).policy(obs)
    np.testing.assert_allclose(got_c, expected, rtol=0, atol=TOLERANCE)


def test_the_normaliser_clip_is_inside_the_exports(exported, tmp_path):
    """Observations far outside the training statistics (a sensor fault, a saturated channel):
    the normalised values hit VecNormalize's clip (10), which rollouts rarely reach."""
    policy = SB3Policy.load(PRETRAINED_DIR / "ppo-measured.zip")
    mean, std = policy.obs_rms.mean, np.sqrt(policy.obs_rms.var + policy.epsilon)
    signs = np.random.default_rng(3).choice([-1.0, 1.0], size=(500, mean.size))
    obs = mean + signs * std * np.random.default_rng(4).uniform(5, 40, (500, mean.size))
    obs = obs.astype(np.float32)
    assert np.mean(np.abs(policy.normalize(obs)) == 10.0) > 0.5
    expected, _ = policy.predict(obs, deterministic=True)
    files = exported["ppo-measured"]
    onnx = ort.InferenceSession(str(files["ppo-measured.onnx"]), providers=["CPUExecutionProvider"])
    np.testing.assert_allclose(onnx.run(None, {"obs": obs})[0], expected, rtol=0, atol=TOLERANCE)
    got_c = c_policy(files, "ppo-measured", obs.shape[1], tmp_path).policy(obs)
    np.testing.assert_allclose(got_c, expected, rtol=0, atol=TOLERANCE)


def test_the_contract_states_what_the_env_and_the_files_are(exported):
    files = exported["ppo-measured"]
    card = json.loads(files["ppo-measured.contract.json"].read_text())
    env = CapsuleSuspensionVectorEnv(num_envs=1, setting="hils", observation="measured")
    assert [c["name"] for c in card["observation"]["columns"]] == list(env.config.observation_names)
    assert card["observation"]["columns"][0]["unit"] in ("m/s^2", "m/s²")
    assert card["task"] == "CapsuleRide-v0"
    assert card["control"]["period_s"] == pytest.approx(0.005)
    assert card["control"]["delay_steps"] == 1 and card["control"]["delay_s"] == pytest.approx(
        0.005
    )
    assert card["action"]["mode"] == "force" and card["action"]["max_force_n"] == 8000.0
    with open(PRETRAINED_DIR / "ppo-measured.vecnormalize.pkl", "rb") as fh:
        rms = pickle.load(fh).obs_rms
    means = [c["mean"] for c in card["observation"]["columns"]]
    np.testing.assert_allclose(means, rms.mean, rtol=1e-15)
    recorded = json.loads((PRETRAINED_DIR / "ppo-measured.json").read_text())["digests"]
    assert card["sources"]["model"]["sha256"] == recorded["model"]["sha256"]
    assert card["sources"]["normaliser"]["sha256"] == recorded["normaliser"]["sha256"]
    for file_name in ("ppo-measured.onnx", "ppo-measured.c", "ppo-measured.h"):
        digest = hashlib.sha256(files[file_name].read_bytes()).hexdigest()
        assert card["artifacts"][file_name]["sha256"] == digest
    assert card["residual"] is None


def test_contracts_name_the_task_and_a_residual_law(exported):
    trip = json.loads(exported["ppo-trip"]["ppo-trip.contract.json"].read_text())
    assert trip["task"] == "CapsuleTrip-v0"
    assert [c["name"] for c in trip["observation"]["columns"]][-2:] == [
        "speed_m_s", "longitudinal_acceleration_m_s2"]  # fmt: skip
    hils = json.loads(exported["ppo-hils"]["ppo-hils.contract.json"].read_text())
    assert hils["task"] is None and hils["env_kwargs"]["observation"] == "full_state"
    card = json.loads(exported["residual-ppo-mpc"]["residual-ppo-mpc.contract.json"].read_text())
    assert card["residual"]["law"] == "mpc-biexp-meas" and card["residual"]["scale"] == 0.5
    assert card["residual"]["rig_provides_law"] and not card["residual"]["law_in_c"]


def _residual_set(folder: Path, law: str) -> Path:
    """``residual-ppo-mpc``'s files copied, its metadata's law changed to ``law``."""
    return residual_copy(folder, "residual-ppo-mpc", law, "res-lqr")


def test_a_residual_on_the_clipped_lqr_exports_its_law_in_c(tmp_path):
    if c_compiler() is None:
        pytest.skip(NO_COMPILER)
    zip_path = _residual_set(tmp_path, "lqr-clipped-biexp-meas")
    files = export_policy(str(zip_path), tmp_path / "out", "c")
    policy = load_policy(zip_path)  # the law plus the residual, as evaluate.py runs it
    obs = rollout_obs(policy, policy.env_kwargs | {"setting": "hils"})
    expected, _ = policy.predict(obs, deterministic=True)
    lib = CPolicy(build_shared(files["res-lqr.c"], tmp_path), obs.shape[1])
    np.testing.assert_allclose(lib.control(obs), expected, rtol=0, atol=TOLERANCE)
    residual, _ = policy.policy.predict(obs, deterministic=True)
    np.testing.assert_allclose(lib.policy(obs), residual, rtol=0, atol=TOLERANCE)
    assert lib.combine(0.9, 0.5) == pytest.approx(1.0) and lib.combine(-0.2, 0.5) == pytest.approx(
        0.05
    )
    card = json.loads(files["res-lqr.contract.json"].read_text())
    assert card["residual"]["law_in_c"] and "k_stroke_n_m" in card["residual"]["law_gains"]


def test_a_residual_export_gives_0_on_a_non_finite_observation(tmp_path):
    """ResidualPolicy gives a row whose observation holds a NaN or inf its law's action alone
    (the residual 0); the ONNX graph and the C file give the residual 0 there, so that the C
    file's capsule_control is the policy's action. The NaN and the infs are in columns the
    clipped LQR does not read (accelerations, the last command): its action stays finite."""
    zip_path = _residual_set(tmp_path, "lqr-clipped-biexp-meas")
    files = export_policy(str(zip_path), tmp_path / "out")
    policy = load_policy(zip_path)
    obs = rollout_obs(policy, policy.env_kwargs | {"setting": "hils"}, vehicles=1, steps=8)
    obs[1, 0], obs[3, 6], obs[5, 1] = np.nan, np.inf, -np.inf
    bad = ~np.all(np.isfinite(obs), axis=1)
    expected, _ = policy.predict(obs, deterministic=True)
    law_alone, _ = policy.law.predict(obs)
    np.testing.assert_array_equal(expected[bad], law_alone[bad])  # the Python rule
    network, _ = policy.policy.predict(np.where(bad[:, None], 0.0, obs), deterministic=True)
    assert np.all(np.abs(network[~bad]) > 1e-3)  # the good rows' residual is not 0
    onnx = ort.InferenceSession(str(files["res-lqr.onnx"]), providers=["CPUExecutionProvider"])
    got_onnx = onnx.run(None, {"obs": obs})[0]
    assert np.all(got_onnx[bad] == 0.0)
    np.testing.assert_allclose(got_onnx[~bad], network[~bad], rtol=0, atol=TOLERANCE)
    lib = c_policy(files, "res-lqr", obs.shape[1], tmp_path)
    assert np.all(lib.policy(obs)[bad] == 0.0)
    np.testing.assert_allclose(lib.policy(obs)[~bad], network[~bad], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(lib.control(obs), expected, rtol=0, atol=TOLERANCE)


C_LAW_NAMES = ["skyhook-biexp", "skyhook-cont-biexp", "hybrid-biexp", "lqr-clipped-biexp",
               "skyhook-cont-biexp-meas", "hybrid-biexp-meas", "lqr-clipped-biexp-meas",
               "skyhook-meas", "add-meas", "sh-add-meas"]  # fmt: skip


@pytest.mark.parametrize("name", C_LAW_NAMES)
def test_the_c_form_of_a_law_is_the_law(name, tmp_path):
    from capsule_env.agents.controllers.classical import make_controller

    from capsule_env.export.laws_c import law_c

    if c_compiler() is None:
        pytest.skip(NO_COMPILER)
    law = make_controller(name)
    source = tmp_path / "law.c"
    source.write_text(law_c(law) + "void capsule_policy(const float *obs, float *a);\n"
                      "void capsule_policy(const float *obs, float *a) { a[0] = capsule_law(obs); }\n")  # fmt: skip
    obs = rollout_obs(law, law.env_kwargs | {"setting": "hils"})
    expected, _ = law.predict(obs)
    assert len(np.unique(expected)) > 1  # both branches (or a spread of forces)
    got = CPolicy(build_shared(source, tmp_path), obs.shape[1]).policy(obs)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)


def _tiny_set(folder: Path, algo: str) -> Path:
    """An untrained ``algo`` model on the ride task with VecNormalize statistics of 64 steps."""
    from capsule_env.agents.learning.algorithms import algorithm_class
    from stable_baselines3.common.vec_env import VecNormalize

    from capsule_env.envs.sb3 import make_sb3_vec_env

    kwargs = {"setting": "hils", "observation": "measured"}
    venv = VecNormalize(make_sb3_vec_env(num_envs=4, seed=1, **kwargs), norm_reward=False)
    venv.reset()
    for _ in range(64):
        venv.step(np.random.default_rng(0).uniform(-1, 1, (4, 1)).astype(np.float32))
    model = algorithm_class(algo)("MlpPolicy", venv, seed=0, device="cpu")
    for module in model.policy.modules():  # CrossQ: running statistics that change the output
        if type(module).__name__ == "BatchRenorm1d":
            module.ra_mean.uniform_(-0.5, 0.5)
            module.ra_var.uniform_(0.5, 2.0)
    model.save(folder / f"{algo}.zip")
    venv.save(str(folder / f"{algo}.vecnormalize.pkl"))
    (folder / f"{algo}.json").write_text(json.dumps({"algo": algo, "env_kwargs": kwargs}))
    return folder / f"{algo}.zip"


@pytest.mark.parametrize("algo", ["sac", "td3", "tqc", "crossq"])
def test_other_algorithms_export_their_deterministic_action(algo, tmp_path):
    if algo in ("tqc", "crossq"):
        pytest.importorskip("sb3_contrib", reason=NO_SB3)
    zip_path = _tiny_set(tmp_path, algo)
    files = export_policy(str(zip_path), tmp_path / "out")
    policy = SB3Policy.load(zip_path)
    obs = rollout_obs(policy, {"setting": "hils", "observation": "measured"}, steps=100)
    expected, _ = policy.predict(obs, deterministic=True)
    assert np.std(expected) > 1e-3
    onnx = ort.InferenceSession(str(files[f"{algo}.onnx"]), providers=["CPUExecutionProvider"])
    np.testing.assert_allclose(onnx.run(None, {"obs": obs})[0], expected, rtol=0, atol=TOLERANCE)
    got_c = c_policy(files, algo, obs.shape[1], tmp_path).policy(obs)
    np.testing.assert_allclose(got_c, expected, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["no-such-policy"], "unknown policy 'no-such-policy'"),
        (["missing/policy.zip"], "does not exist"),
        (["ppo-measured", "--format", "onnx,tflite"], "--format must be"),
        (["ppo-measured", "--format", ""], "--format must be"),
        (["ppo-measured", "--name", "a/b"], "--name must be"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(argv, expected, tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("capsule-export: error: ") and expected in err
    assert not out.exists()


def test_a_residual_on_an_unknown_law_writes_nothing(tmp_path, capsys):
    zip_path = _residual_set(tmp_path, "no-such-law")
    out = tmp_path / "out"
    out.mkdir()
    assert main([str(zip_path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no-such-law" in err
    assert list(out.iterdir()) == []


def test_the_command_refuses_bad_input_in_one_line_without_traceback(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "capsule_env.export", "nope", "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert not out.exists()
