"""A saved policy's files (capsule_env.agents.learning.policy_files): sibling names of dotted stems, and saves
that a kill at any point leaves loadable as the previous complete set or the new one, never a
mix (issue 25 items 1 and 3).

The kills are real: a driver process forks one child per kill point, and the child saves a new
set with every file operation counted (the writes, ``fsync``, ``rename``, ``replace``,
``link``, ``unlink``, ``rmdir``) and ends itself with ``os._exit`` (no handler, no ``finally``
runs) just before operation ``k``; the folder it leaves is kept for the checks, which read it
with the loaders and compare with what each save wrote (a tag in every file).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from capsule_env.agents.learning.checkpoints import (
    checkpoint_problem,
    find_checkpoint,
    latest_checkpoint,
    save_policy,
)
from capsule_env.agents.learning.policy_files import (
    clean_leftovers,
    readable_stem,
    save_file_set,
    set_problem,
    sibling,
)

from conftest import NO_SB3

STEM = "ckpt_000000001024"
POLICY_ENV = {"setting": "hils", "action_mode": "current", "observation": "full_state"}

# The driver: saves the "old" set, then for k = 0, 1, ... restores it, forks a child that saves
# the "new" set and exits at operation k, and moves what the child left to OUT/k.
DRIVER = r"""
import json, os, shutil, sys
from pathlib import Path
from capsule_env.agents.learning.checkpoints import save_policy

folder, out, new_buffer = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1"
stem = folder / "checkpoints" / "ckpt_000000001024"
KILL_AT, count = None, 0

def tick():
    global count
    if count == KILL_AT:
        os._exit(0)
    count += 1

def write(path, text):
    data = text.encode()
    with open(path, "wb") as fh:
        fh.write(data[: len(data) // 2])
        fh.flush()
        tick()  # a kill half-way through a write
        fh.write(data[len(data) // 2 :])

class Stats:
    def __init__(self, tag): self.tag = tag
    def save(self, path): write(path, f"statistics {self.tag}")

class Model:
    num_timesteps = 1024
    def __init__(self, tag): self.tag = tag
    def get_vec_normalize_env(self): return Stats(self.tag)
    def save(self, path): write(path, f"model {self.tag} " * 500)
    def save_replay_buffer(self, path): write(path, f"buffer {self.tag} " * 2000)

def save(tag, buffer):
    meta = {"algo": "ppo", "num_envs": 4, "train_env_kwargs": {}, "num_timesteps": 1024,
            "generation": tag}
    save_policy(Model(tag), stem, meta, replay_buffer=buffer)

save("old", True)
initial = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
for name in ("fsync", "rename", "replace", "link", "unlink", "rmdir"):
    real = getattr(os, name)
    setattr(os, name, lambda *a, _real=real, **k: (tick(), _real(*a, **k))[1])
out.mkdir(parents=True)
for k in range(1000):
    for rel, data in initial.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    pid = os.fork()
    if pid == 0:
        KILL_AT, count = k, 0
        try:
            save("new", new_buffer)
        finally:
            os._exit(3)
    status = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    if status == 3:  # the save finished before operation k: every point was covered
        folder.rename(out / "finished")
        print(json.dumps({"operations": k}))
        break
    assert status == 0, status
    folder.rename(out / str(k))  # as the kill left it (hard links too)
"""


def generation_of(stem: Path) -> str:
    """The tag of the complete set at ``stem``, checked file by file against what the
    driver's save of that tag wrote (independently of the digests the loaders check)."""
    meta = json.loads(sibling(stem, ".json").read_text())
    tag = meta["generation"]
    expected = {".zip": f"model {tag} " * 500, ".vecnormalize.pkl": f"statistics {tag}"}
    if "replay_buffer" in meta["digests"] or sibling(stem, ".replay_buffer.pkl").is_file():
        expected[".replay_buffer.pkl"] = f"buffer {tag} " * 2000
    for suffix, text in expected.items():
        assert sibling(stem, suffix).read_text() == text, (stem, suffix)
    return tag


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the kills are forked children (POSIX)")
@pytest.mark.parametrize("new_buffer", [True, False], ids=["with-buffer", "buffer-dropped"])
def test_a_kill_at_any_point_of_a_save_leaves_the_old_or_the_new_set(tmp_path, new_buffer):
    out = tmp_path / "states"
    result = subprocess.run(
        [sys.executable, "-c", DRIVER, str(tmp_path / "run"), str(out), str(int(new_buffer))],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    operations = json.loads(result.stdout)["operations"]
    assert operations >= 20  # writes, fsyncs, the commit, links, renames, removals
    seen = []
    for k in range(operations):
        run = out / str(k)
        ckpt_dir = run / "checkpoints"
        stem = ckpt_dir / STEM
        assert checkpoint_problem(sibling(stem, ".zip")) is None, k
        tag = generation_of(readable_stem(stem))
        assert generation_of(sibling(latest_checkpoint(run), "")) == tag, k
        assert find_checkpoint("auto", run)[1]["generation"] == tag, k
        seen.append(tag)
        # the next start finishes or removes what the kill left, and changes nothing else
        clean_leftovers(ckpt_dir)
        assert hidden(ckpt_dir) == [], k
        assert set_problem(stem) is None and generation_of(stem) == tag, k
    # old until the commit (one rename), new from then on; never a mix in between
    first_new = seen.index("new")
    assert seen == ["old"] * first_new + ["new"] * (operations - first_new)
    assert 0 < first_new < operations - 3  # the publication after the commit was cut too
    finished = out / "finished" / "checkpoints"
    assert hidden(finished) == [] and generation_of(finished / STEM) == "new"
    buffer = sibling(finished / STEM, ".replay_buffer.pkl")
    assert buffer.is_file() == new_buffer  # a dropped buffer does not outlive its set


def test_a_kill_leaves_temporary_files_that_the_next_save_removes(tmp_path):
    stem = tmp_path / "best_model"

    def writer(tag: str):
        def write(temp: Path) -> None:
            sibling(temp, ".zip").write_text(f"zip {tag}")
            sibling(temp, ".json").write_text(json.dumps({"generation": tag}))

        return write

    save_file_set(stem, writer("old"))
    # what kills leave: a staging folder, a file of the older per-file staging, a commit
    # folder whose removal had begun (its json gone: the public set is already the new one)
    (tmp_path / ".best_model.0123abcd.tmp").mkdir()
    (tmp_path / ".best_model.0123abcd.tmp" / "best_model.zip").write_text("half")
    (tmp_path / ".best_model.zip.89abcdef.tmp").write_text("half")
    (tmp_path / ".best_model.commit").mkdir()
    (tmp_path / ".best_model.commit" / "best_model.zip").write_text("zip old")
    (tmp_path / ".other.89abcdef.tmp").write_text("another stem's: left alone")
    assert readable_stem(stem) == stem  # an incomplete commit folder is not read
    save_file_set(stem, writer("new"))
    assert hidden(tmp_path) == [".other.89abcdef.tmp"]
    assert sibling(stem, ".zip").read_text() == "zip new"
    clean_leftovers(tmp_path)  # a start cleans every stem's
    assert hidden(tmp_path) == []
    with pytest.raises(ValueError, match="best_model.json"):
        save_file_set(stem, lambda temp: sibling(temp, ".zip").write_text("no json"))
    assert hidden(tmp_path) == [] and sibling(stem, ".zip").read_text() == "zip new"


def test_sibling_keeps_every_dot_of_the_stem():
    assert sibling(Path("runs/cur.v1.zip"), ".json") == Path("runs/cur.v1.json")
    assert sibling("runs/cur.v1", ".vecnormalize.pkl") == Path("runs/cur.v1.vecnormalize.pkl")
    assert sibling("a.b.c.zip", "") == Path("a.b.c")


# ------------------------------------------------------------------- real SB3 policies
def _save_tiny(stem: Path, env_kwargs: dict, name: str, timesteps: int = 0,
               env_steps: int = 0) -> object:  # fmt: skip
    """An untrained PPO saved as train.py saves one, trained with ``env_kwargs``; its
    normalisation statistics updated by ``env_steps`` steps of random actions (seeded by
    ``timesteps``)."""
    pytest.importorskip("stable_baselines3", reason=NO_SB3)
    from capsule_env.agents.learning.training import make_env
    from stable_baselines3 import PPO

    venv = make_env(2, 0, env_kwargs, {"norm_obs": True, "norm_reward": True})
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, seed=timesteps, device="cpu")
    venv.reset()
    rng = np.random.default_rng(timesteps)
    for _ in range(env_steps):
        venv.step(rng.uniform(-1.0, 1.0, size=(2, 1)).astype(np.float32))
    model.num_timesteps = timesteps
    meta = {"algo": "ppo", "name": name, "env_kwargs": env_kwargs, "num_timesteps": timesteps,
            "num_envs": 2, "train_env_kwargs": env_kwargs}  # fmt: skip
    save_policy(model, stem, meta)
    return model


@pytest.mark.rl
def test_a_dotted_policy_name_reads_its_own_metadata(tmp_path):
    from capsule_env.agents.learning.sb3_policy import SB3Policy

    from capsule_env.evaluation import evaluate

    _save_tiny(tmp_path / "cur.v1", POLICY_ENV, "cur-v1")
    # a decoy where Path.with_suffix would look: force mode, no digests
    (tmp_path / "cur.json").write_text(json.dumps({"algo": "ppo", "name": "decoy",
                                                   "env_kwargs": {"action_mode": "force"}}))  # fmt: skip
    policy = SB3Policy.load(tmp_path / "cur.v1.zip")
    assert policy.name == "cur-v1" and policy.env_kwargs["action_mode"] == "current"
    ctrls = evaluate.build_controllers([], [str(tmp_path / "cur.v1.zip")], shipped=False)
    assert ctrls["cur-v1"].env_kwargs == {"action_mode": "current", "observation": "full_state"}
    ckpt, meta = find_checkpoint(str(tmp_path / "cur.v1.zip"), tmp_path)
    assert meta["name"] == "cur-v1" and ckpt == tmp_path / "cur.v1.zip"
    # the digests of cur.v1.json are checked: statistics changed after the save are refused
    pkl = tmp_path / "cur.v1.vecnormalize.pkl"
    data = bytearray(pkl.read_bytes())
    data[-3] ^= 0xFF
    pkl.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"does not match cur\.v1\.json"):
        SB3Policy.load(tmp_path / "cur.v1.zip")
    assert "cur.v1.vecnormalize.pkl" in checkpoint_problem(tmp_path / "cur.v1.zip")


class Killed(BaseException):
    """Stands for a SIGKILL after the commit: nothing after it runs (no handler there)."""


@pytest.mark.rl
def test_a_save_cut_after_its_commit_loads_the_new_policy(tmp_path, monkeypatch):
    from capsule_env.agents.learning import policy_files
    from capsule_env.agents.learning.sb3_policy import SB3Policy

    stem = tmp_path / "best_model"
    old = _save_tiny(stem, POLICY_ENV, "tiny", timesteps=1)
    new = _save_tiny(tmp_path / "other", POLICY_ENV, "tiny", timesteps=2)
    real_replace, calls = os.replace, []

    def cut(src, dst, *a, **k):
        calls.append(dst)
        if len(calls) == 2:  # the .zip is the new one, the statistics and json the old ones
            raise Killed
        return real_replace(src, dst, *a, **k)

    monkeypatch.setattr(policy_files.os, "replace", cut)
    with pytest.raises(Killed):
        save_policy(new, stem, {"algo": "ppo", "name": "tiny", "env_kwargs": POLICY_ENV,
                                "num_timesteps": 2})  # fmt: skip
    monkeypatch.undo()
    assert set_problem(stem) is not None  # the public files are mixed ...
    policy = SB3Policy.load(sibling(stem, ".zip"))  # ... the loader reads the committed set
    assert policy.meta["num_timesteps"] == 2
    obs = np.random.default_rng(0).normal(size=(8, policy.obs_rms.mean.shape[0]))
    statistics = new.get_vec_normalize_env()
    expected, _ = new.predict(statistics.normalize_obs(obs.astype(np.float32)), deterministic=True)
    np.testing.assert_allclose(policy.predict(obs)[0], np.clip(expected, -1, 1), atol=1e-6)
    before, _ = old.predict(statistics.normalize_obs(obs.astype(np.float32)), deterministic=True)
    assert np.abs(before - expected).max() > 1e-3  # the two saves' models act differently
    clean_leftovers(tmp_path)  # train.py's start: the committed set is published
    assert hidden(tmp_path) == [] and set_problem(stem) is None
    assert SB3Policy.load(sibling(stem, ".zip")).meta["num_timesteps"] == 2


@pytest.mark.rl
def test_shipped_policies_still_load():
    from capsule_env.agents.learning.sb3_policy import SB3Policy, shipped_policy_paths

    for path in shipped_policy_paths():  # saved before the commit folders: plain files
        assert set_problem(path) is None and readable_stem(path) == sibling(path, "")
        assert SB3Policy.load(path).obs_rms is not None


# ------------------------------------------------------------- sets bound by content
def _copy_set(sources: dict[str, Path], stem: Path) -> Path:
    """The files ``sources`` (``{suffix: file}``) copied as the set ``stem``; its ``.zip``."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    for suffix, source in sources.items():
        sibling(stem, suffix).write_bytes(source.read_bytes())
    return sibling(stem, ".zip")


def _two_runs(tmp_path: Path) -> tuple[Path, Path]:
    """``best_model`` of two tiny runs (other weights, other statistics), as train.py saves."""
    runs = tmp_path / "run-a" / "best_model", tmp_path / "run-b" / "best_model"
    for k, stem in enumerate(runs):
        _save_tiny(stem, POLICY_ENV, f"run-{'ab'[k]}", timesteps=k + 1, env_steps=5 + k)
    for suffix in (".zip", ".vecnormalize.pkl"):  # the runs' files differ: a mix is a mix
        assert sibling(runs[0], suffix).read_bytes() != sibling(runs[1], suffix).read_bytes()
    return runs


def _members(run: Path) -> dict[str, Path]:
    return {s: sibling(run, s) for s in (".zip", ".vecnormalize.pkl", ".json")}


@pytest.mark.rl
def test_a_renamed_intact_set_loads_and_acts_as_the_original(tmp_path):
    from capsule_env.agents.learning.sb3_policy import SB3Policy

    run_a, _ = _two_runs(tmp_path)
    original = SB3Policy.load(sibling(run_a, ".zip"))
    backup = _copy_set(_members(run_a), tmp_path / "backup" / "a.best.2026")
    renamed = _copy_set(_members(run_a), run_a.parent / "best_model_old")  # next to the set
    obs = np.random.default_rng(0).normal(size=(16, original.obs_rms.mean.shape[0]))
    for path in (backup, renamed):
        assert set_problem(path) is None, path
        policy = SB3Policy.load(path)
        assert policy.name == "run-a"
        np.testing.assert_array_equal(policy.predict(obs)[0], original.predict(obs)[0])
        np.testing.assert_array_equal(policy.obs_rms.var, original.obs_rms.var)
        assert find_checkpoint(str(path), tmp_path)[0] == path  # --resume from a copy
    # a checkpoint copied elsewhere under its own name resumes too
    ckpt = _copy_set(_members(run_a), tmp_path / "elsewhere" / "ckpt_000000000001")
    assert checkpoint_problem(ckpt) is None
    # a member its metadata does not record (another save's replay buffer) is not the set's
    sibling(backup, ".replay_buffer.pkl").write_bytes(b"another save's buffer")
    assert "replay_buffer a.best.2026.replay_buffer.pkl" in (set_problem(backup) or "")


@pytest.mark.rl
@pytest.mark.parametrize(
    ("mix", "role", "wrong"),
    [({".zip": 0, ".vecnormalize.pkl": 1, ".json": 1}, "model", ".zip"),
     ({".zip": 0, ".vecnormalize.pkl": 1, ".json": 0}, "normaliser", ".vecnormalize.pkl"),
     ({".zip": 1, ".vecnormalize.pkl": 1, ".json": 0}, "model", ".zip")],
    ids=["model-of-a", "statistics-of-b", "metadata-of-a"],
)  # fmt: skip
def test_a_set_mixed_from_two_runs_is_refused_naming_the_role(tmp_path, capsys, mix, role, wrong):
    from capsule_env.agents.learning.sb3_policy import SB3Policy

    from capsule_env.evaluation import evaluate

    runs = _two_runs(tmp_path)
    path = _copy_set({s: sibling(runs[k], s) for s, k in mix.items()}, tmp_path / "mix" / "p")
    json_name, wrong_name = "p.json", sibling(path, wrong).name
    with pytest.raises(ValueError, match=rf"{role} {wrong_name}\b.*{json_name}") as info:
        SB3Policy.load(path)
    assert len(str(info.value).splitlines()) == 1
    assert f"{role} {wrong_name}" in (set_problem(path) or "")
    assert f"{role} {wrong_name}" in (checkpoint_problem(path) or "")
    argv = ["--episodes", "1", "--episode-length", "1", "--setting", "hils", "--controllers",
            "passive", "--no-shipped-policy", "--policy", str(path)]  # fmt: skip
    with pytest.raises(SystemExit) as exited:
        evaluate.main(argv)
    message = str(exited.value.code)
    assert message.startswith("evaluate.py: error:") and f"{role} {wrong_name}" in message
    assert "\n" not in message and "Traceback" not in capsys.readouterr().err


@pytest.mark.rl
def test_metadata_of_the_earlier_format_is_checked_by_role_too(tmp_path):
    """Metadata written before the digests by role (``files``: by the file names of the save)
    still binds its set: each recorded file's role is its name's suffix."""
    from capsule_env.agents.learning.sb3_policy import SB3Policy

    from capsule_env.common.safe_io import file_digest

    runs = _two_runs(tmp_path)
    for run in runs:
        buffer = sibling(run, ".replay_buffer.pkl")
        buffer.write_bytes(f"buffer of {run.parent.name}".encode())
        meta = json.loads(sibling(run, ".json").read_text())
        meta.pop("digests")
        meta["files"] = {sibling(run, s).name: file_digest(sibling(run, s))
                         for s in (".zip", ".vecnormalize.pkl")}  # fmt: skip
        meta["replay_buffer"] = {buffer.name: file_digest(buffer)}
        sibling(run, ".json").write_text(json.dumps(meta))
    members = dict(
        _members(runs[0]), **{".replay_buffer.pkl": sibling(runs[0], ".replay_buffer.pkl")}
    )
    renamed = _copy_set(members, tmp_path / "backup" / "old-format")
    assert set_problem(renamed) is None and SB3Policy.load(renamed).name == "run-a"
    sibling(renamed, ".replay_buffer.pkl").write_bytes(b"buffer of run-b")
    assert "replay_buffer old-format.replay_buffer.pkl" in (set_problem(renamed) or "")
    mixed = dict(_members(runs[1]), **{".zip": sibling(runs[0], ".zip")})
    path = _copy_set(mixed, tmp_path / "mix" / "old-format")
    with pytest.raises(ValueError, match=r"model old-format\.zip"):
        SB3Policy.load(path)
