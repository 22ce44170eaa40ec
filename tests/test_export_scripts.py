"""Issue 44, item 3: the latency benchmark and the HILS dry run of exported policies run, and the
dry run's loop drives the env as the policy itself would (the same episode, step for step)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import NO_SB3, load_script

pytest.importorskip("stable_baselines3", reason=NO_SB3)
EXPORT_EXTRA = "optional, in the export extra: pip install 'capsule-env[export]'"
pytest.importorskip("onnxruntime", reason=f"onnxruntime is not installed ({EXPORT_EXTRA})")
pytest.importorskip("onnxscript", reason=f"onnxscript is not installed ({EXPORT_EXTRA})")

from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy  # noqa: E402

from capsule_env.envs import CapsuleSuspensionEnv  # noqa: E402
from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.c_build import c_compiler  # noqa: E402

pytestmark = pytest.mark.rl
NO_COMPILER = "no C compiler on this machine (cc, gcc, clang or $CC): the C export is not built"


@pytest.fixture(scope="module")
def contract(tmp_path_factory):
    out = tmp_path_factory.mktemp("exported")
    return export_policy("ppo-measured", out)["ppo-measured.contract.json"]


def test_the_benchmark_times_each_runtime(tmp_path):
    if c_compiler() is None:
        pytest.skip(NO_COMPILER)
    bench = load_script("benchmarks/bench_export.py")
    out = tmp_path / "bench.json"
    assert bench.main(["--quick", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert set(res["runtimes"]) == {"sb3", "onnxruntime", "c", "c-ctypes"}
    for stats in res["runtimes"].values():
        assert stats["calls"] >= 200
        assert 0 < stats["median_us"] <= stats["p99_us"] <= stats["max_us"]
    assert res["machine"]["cpu"]


def reference_rms(seconds: float, seed: int) -> float:
    """The RMS car-body acceleration of the episode the dry run runs, driven by the policy
    itself (``SB3Policy.predict``) in an env built here."""
    policy = SB3Policy.load(PRETRAINED_DIR / "ppo-measured.zip")
    kwargs = json.loads((PRETRAINED_DIR / "ppo-measured.json").read_text())["env_kwargs"]
    env = CapsuleSuspensionEnv(**kwargs, episode_length_s=seconds + 1.0, guideway_seed=3)
    obs, _ = env.reset(seed=seed)
    acc = []
    for _ in range(int(round(seconds / 0.005))):
        action, _ = policy.predict(obs[None], deterministic=True)
        obs, _, _, _, info = env.step(action[0])
        acc.append(info["car_body_acceleration_m_s2"])
    return float(np.sqrt(np.mean(np.square(acc))))


@pytest.mark.parametrize("runtime", ["c", "onnx"])
def test_the_dry_run_drives_the_episode_the_policy_drives(runtime, contract, tmp_path):
    if runtime == "c" and c_compiler() is None:
        pytest.skip(NO_COMPILER)
    dry = load_script("benchmarks/hils_dry_run.py")
    out = tmp_path / "run.json"
    assert (
        dry.main([str(contract), "--runtime", runtime, "--seconds", "1", "--json", str(out)]) == 0
    )
    res = json.loads(out.read_text())
    assert res["steps"] == 200 and 0 <= res["deadlines_missed"] <= res["overruns"] <= 200
    assert res["rms_body_acc_m_s2"] == pytest.approx(reference_rms(1.0, 40), rel=1e-4)
    assert not list(contract.parent.glob("*.so"))  # built elsewhere, not beside the artifacts


def test_the_dry_run_refuses_an_artifact_the_contract_does_not_record(contract, tmp_path, capsys):
    folder = tmp_path / "copy"
    folder.mkdir()
    for path in contract.parent.glob("ppo-measured.*"):
        (folder / path.name).write_bytes(path.read_bytes())
    with open(folder / "ppo-measured.c", "a") as fh:
        fh.write("/* edited */\n")
    dry = load_script("benchmarks/hils_dry_run.py")
    assert dry.main([str(folder / "ppo-measured.contract.json"), "--seconds", "0.5"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not the file" in err
