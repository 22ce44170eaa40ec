"""Saving trained policies and checkpoints, and resuming from them (``train.py``).

A saved policy is a set of files with one stem: ``stem.zip`` (the SB3 model),
``stem.vecnormalize.pkl`` (its ``VecNormalize`` statistics), for SAC/TD3 checkpoints
``stem.replay_buffer.pkl``, and ``stem.json`` (metadata: name, algorithm, env arguments,
timesteps, wall time, the run's arguments, and the sizes and SHA-256 of the other files by
role, ``digests``: the set is bound by content, not by its file names).
:func:`save_policy` replaces a set in one atomic step (:func:`capsule_env.agents.learning.policy_files.save_file_set`:
the new files are written into a hidden folder, committed by one rename, then published): a full
disk or a kill at any point leaves the previous complete set or the new one readable, never a
mix, and the loaders (:func:`checkpoint_problem`, ``capsule_env.agents.learning.sb3_policy.SB3Policy.load``)
read the committed set (:func:`capsule_env.agents.learning.policy_files.readable_stem`) and refuse a set mixed
from two saves or truncated later.

Checkpoints are ``<output>/checkpoints/ckpt_<timesteps, 12 digits>.*``; only the newest
``keep_replay_buffers`` keep their replay buffer (:func:`prune_replay_buffers`).
``--resume auto`` takes the newest intact one (:func:`latest_checkpoint`), reporting each newer
damaged one on stderr.

Resuming uses SB3's public API only (:func:`resume_model`): ``Algo.load(zip, env=env)``, with
the checkpoint's statistics loaded into the env's ``VecNormalize``, ``load_replay_buffer`` for
SAC/TD3, then ``model.learn(..., reset_num_timesteps=False)``. ``Algo.load`` discards the
saved last observation (its ``force_reset``), so ``learn`` starts by resetting the env, and
that reset, in training mode, updates the observation statistics with one batch of
observations (``num_envs`` samples, against the checkpoint's millions): the resumed run starts
from the checkpoint's statistics plus that one batch, not from exactly the checkpoint's.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

from capsule_env.agents.learning.policy_files import (
    commit_dir,
    member_digests,
    readable_stem,
    recorded_digests,
    save_file_set,
    set_problem,
    sibling,
)


def save_policy(model: Any, stem: Path, meta: dict, replay_buffer: bool = False) -> None:
    """``stem.zip`` (model), ``stem.vecnormalize.pkl`` (statistics), optionally
    ``stem.replay_buffer.pkl`` (SAC/TD3), and ``stem.json`` (metadata), saved together in one
    atomic step (:func:`capsule_env.agents.learning.policy_files.save_file_set`): a failed save (a full disk,
    a kill) leaves the previous set or the new one, complete. The json records the size and
    SHA-256 of the model, the statistics and the replay buffer by role (``digests``,
    :func:`capsule_env.agents.learning.policy_files.member_digests`), which the loaders check
    (:func:`checkpoint_problem`, ``capsule_env.agents.learning.sb3_policy.SB3Policy.load``): a mixed or
    truncated set is refused, a set copied under other names loads.
    """
    stem = Path(stem)

    def write(temp: Path) -> None:
        zip_path, pkl_path = sibling(temp, ".zip"), sibling(temp, ".vecnormalize.pkl")
        rb_path = sibling(temp, ".replay_buffer.pkl")
        model.get_vec_normalize_env().save(str(pkl_path))
        if replay_buffer:
            model.save_replay_buffer(str(rb_path))
        model.save(str(zip_path))
        full = {**meta, "digests": member_digests(temp)}  # by role, not by file name
        sibling(temp, ".json").write_text(json.dumps(full, indent=2, default=str))

    save_file_set(stem, write)


def save_checkpoint(model: Any, ckpt_dir: Path, meta: dict, keep_replay_buffers: int = 2) -> Path:
    """``ckpt_dir/ckpt_<steps>.*`` (:func:`save_policy`; SAC/TD3 with the replay buffer unless
    ``keep_replay_buffers`` is 0), then :func:`prune_replay_buffers`. Returns the ``.zip``."""
    stem = Path(ckpt_dir) / f"ckpt_{model.num_timesteps:012d}"
    with_buffer = hasattr(model, "save_replay_buffer") and keep_replay_buffers > 0
    save_policy(model, stem, {**meta, "num_timesteps": int(model.num_timesteps)}, with_buffer)
    if hasattr(model, "save_replay_buffer"):
        prune_replay_buffers(ckpt_dir, keep_replay_buffers)
    return sibling(stem, ".zip")


def prune_replay_buffers(ckpt_dir: Path, keep: int) -> list[Path]:
    """Delete the ``.replay_buffer.pkl`` files of all but the newest ``keep`` checkpoints (by
    their timesteps); the checkpoints' models stay. Returns the deleted paths."""
    buffers = sorted(Path(ckpt_dir).glob("ckpt_*.replay_buffer.pkl"))  # zero-padded steps
    doomed = buffers[: max(len(buffers) - keep, 0)]
    for path in doomed:
        path.unlink(missing_ok=True)
    return doomed


def checkpoint_problem(zip_path: Path) -> str | None:
    """Why the checkpoint ``zip_path`` (with its ``.vecnormalize.pkl`` and ``.json``, and
    ``.replay_buffer.pkl`` when present; the committed set of a save cut off after its commit,
    :func:`capsule_env.agents.learning.policy_files.readable_stem`) cannot be resumed from, or None when it is
    intact.

    Checked: the json (the mark of a complete save) is readable checkpoint metadata; the files
    exist and, when the json records their sizes and SHA-256 (:func:`save_policy`), match
    them; else (older checkpoints) the zip is a readable zip archive and the statistics
    unpickle.
    """
    stem = readable_stem(zip_path)
    zip_path, name = sibling(stem, ".zip"), sibling(zip_path, "").name
    meta_path, pkl_path = sibling(stem, ".json"), sibling(stem, ".vecnormalize.pkl")
    if not meta_path.is_file():
        return f"no {meta_path.name} (the save did not finish)"
    try:
        meta = json.loads(meta_path.read_text())
        steps = int(meta["num_timesteps"])
    except (OSError, UnicodeDecodeError, ValueError, TypeError, KeyError) as exc:
        return f"{meta_path.name} is not readable checkpoint metadata ({type(exc).__name__}: {exc})"
    missing = [k for k in ("algo", "num_envs", "train_env_kwargs") if k not in meta]
    if missing:
        return f"{meta_path.name} lacks {', '.join(missing)}"
    if f"ckpt_{steps:012d}" != name and name.startswith("ckpt_"):
        return f"{meta_path.name} says {steps} timesteps, not those of its name"
    for path in (zip_path, pkl_path):
        if not path.is_file() or path.stat().st_size == 0:
            return f"{path.name} is missing or empty"
    if recorded_digests(meta) is not None:
        return set_problem(stem)
    try:  # a checkpoint from before the digests: check that the files can be read
        import pickle
        import zipfile

        with zipfile.ZipFile(zip_path) as archive:
            bad = archive.testzip()
        if bad is not None:
            return f"{zip_path.name}: member {bad} is corrupt"
        with pkl_path.open("rb") as fh:
            pickle.load(fh)
    except Exception as exc:  # a corrupt archive or pickle raises many types
        return f"cannot read it ({type(exc).__name__}: {exc})"
    return None


#: What a run writes in its folder besides ``checkpoints/`` (and what its killed saves leave,
#: the same names behind a dot): another file there (a hyperparameter file, notes) is no run's.
RUN_FILES = ("best_model", "final_model", "evaluations.jsonl")


def check_fresh_run_dir(output_dir: Path) -> None:
    """A new run starts only in a folder that holds no other run's files: ``ValueError``
    naming what is there and the two ways on (``--resume auto`` when a checkpoint exists; a
    folder of its own, or removing this one), so that no run's ``best_model``, checkpoints or
    ``evaluations.jsonl`` are replaced by or mixed with another's. A folder without them (and
    with an empty ``checkpoints/``) is fine."""
    if not output_dir.is_dir():
        return
    ckpt_dir = output_dir / "checkpoints"
    found = sorted(p.name for p in output_dir.iterdir()
                   if p.name.lstrip(".").startswith(RUN_FILES))  # fmt: skip
    if ckpt_dir.is_dir():
        found += sorted(f"checkpoints/{p.name}" for p in ckpt_dir.iterdir())
    if not found:
        return
    shown = ", ".join(found[:3]) + (f" and {len(found) - 3} more" if len(found) > 3 else "")
    if any(ckpt_dir.glob("ckpt_*.zip")):
        way = "continue that run with --resume auto, or start afresh"
    else:
        way = "it has no checkpoint to continue from (stopped before its first); start afresh"
    raise ValueError(
        f"--output-dir {output_dir} holds another run's files ({shown}): {way} with another "
        "--output-dir, or remove that folder first; a new run never writes over a run's files"
    )


class RunFolderLock:
    """An exclusive lock on a run folder while one ``train.py`` works in it: ``flock`` on the
    folder itself (no file is made), released when the process ends, killed or not. A second
    process that tries it (a run started twice at once, a ``--resume`` of a run still going)
    gets ``ValueError``: two processes never save into one folder, nor does one clean up the
    other's save in progress (:func:`capsule_env.agents.learning.policy_files.clean_leftovers`). Where folders
    cannot be locked (Windows, some network file systems) it does nothing."""

    def __init__(self) -> None:
        self.fd: int | None = None

    def acquire(self, folder: Path) -> None:
        """Lock ``folder`` if it exists and this holds no lock yet."""
        if self.fd is not None or not Path(folder).is_dir():
            return
        try:
            import fcntl
        except ImportError:  # Windows
            return
        fd = os.open(folder, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise ValueError(f"--output-dir {folder} is in use by another train.py (it holds "
                             "the folder's lock): let that run end, or give another "
                             "--output-dir") from None  # fmt: skip
        except OSError:  # no locks on this file system
            os.close(fd)
            return
        self.fd = fd

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> RunFolderLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def latest_checkpoint(output_dir: Path) -> Path:
    """The ``.zip`` of the newest intact checkpoint in ``output_dir/checkpoints``
    (:func:`checkpoint_problem`; in its commit folder when a save was cut off after its
    commit); each newer one that is not intact is reported on stderr, with the reason, and
    skipped."""
    ckpt_dir = Path(output_dir) / "checkpoints"
    stems = {p.name.split(".")[0] for p in ckpt_dir.glob("ckpt_*.*")}
    stems |= {p.name.split(".")[1] for p in ckpt_dir.glob(".ckpt_*.commit") if p.is_dir()}
    if not stems:
        raise ValueError(f"--resume auto: no checkpoint in {ckpt_dir}")
    skipped = 0
    for name in sorted(stems, reverse=True):  # zero-padded timesteps: newest first
        zip_path = ckpt_dir / f"{name}.zip"
        problem = checkpoint_problem(zip_path)
        if problem is None:
            return sibling(readable_stem(zip_path), ".zip")
        skipped += 1
        print(f"--resume auto: skipping {zip_path}: {problem}", file=sys.stderr, flush=True)
    raise ValueError(f"--resume auto: no intact checkpoint in {ckpt_dir} ({skipped} skipped)")


def find_checkpoint(resume: str, output_dir: Path) -> tuple[Path, dict]:
    """The checkpoint ``--resume`` names and its metadata, checked to be intact; ``ValueError``
    (one line) otherwise. ``resume``: ``auto`` or a run folder (:func:`latest_checkpoint` of
    ``output_dir``, the caller's run folder), or a checkpoint's ``.zip``."""
    if resume == "auto" or Path(resume).is_dir():
        ckpt = latest_checkpoint(output_dir)
    else:
        ckpt = Path(resume)
        if not ckpt.is_file() and not commit_dir(ckpt).is_dir():
            raise ValueError(f"--resume: no checkpoint {ckpt}")
        problem = checkpoint_problem(ckpt)
        if problem:
            raise ValueError(f"--resume: cannot resume from {ckpt}: {problem}")
        ckpt = sibling(readable_stem(ckpt), ".zip")
    meta = json.loads(sibling(ckpt, ".json").read_text())
    return ckpt, meta


def statistics_path(ckpt: Path) -> Path:
    """The ``.vecnormalize.pkl`` of the checkpoint ``ckpt`` (a ``.zip``)."""
    return sibling(ckpt, ".vecnormalize.pkl")


def resume_model(algo_cls: Any, ckpt: Path, env: Any, **load_kwargs: Any) -> Any:
    """The model of the checkpoint ``ckpt`` on ``env`` (whose ``VecNormalize`` holds the
    checkpoint's statistics), with its replay buffer for SAC/TD3 when the checkpoint kept one.

    SB3's public API only: ``algo_cls.load(ckpt, env=env)`` discards the saved last
    observation, so the caller's ``model.learn(..., reset_num_timesteps=False)`` first resets
    the env, which adds that one batch of observations to the statistics (see the module
    docstring). Raises ``SystemExit`` (one line) when the model does not load on ``env``.
    """
    try:
        model = algo_cls.load(str(ckpt), env=env, **load_kwargs)
    except Exception as exc:  # e.g. the env's spaces differ from the checkpoint's
        env.close()
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SystemExit(f"train.py: error: --resume: cannot load {ckpt}: {reason}") from None
    buffer = sibling(ckpt, ".replay_buffer.pkl")
    if hasattr(model, "load_replay_buffer"):
        if buffer.is_file():
            model.load_replay_buffer(str(buffer))
        else:
            print(f"note: {ckpt} has no replay buffer (--keep-replay-buffers keeps only the "
                  "newest ones): the replay buffer starts empty", file=sys.stderr)  # fmt: skip
    print(f"resumed {ckpt} at {model.num_timesteps} timesteps")
    return model


def saved_at(stem: Path, num_timesteps: int) -> bool:
    """Whether the policy set ``stem`` (e.g. ``final_model``) is complete
    (:func:`capsule_env.agents.learning.policy_files.set_problem`) and saved at ``num_timesteps``."""
    readable = readable_stem(stem)
    if set_problem(readable) is not None:
        return False
    try:
        return (
            json.loads(sibling(readable, ".json").read_text()).get("num_timesteps") == num_timesteps
        )
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return False


def logged_timesteps(log: Path) -> list[int]:
    """The ``num_timesteps`` of every readable line of the log ``log`` (``evaluations.jsonl``;
    none when it is missing)."""
    if not Path(log).is_file():
        return []
    steps = []
    for line in Path(log).read_text(errors="replace").splitlines():
        try:
            steps.append(int(json.loads(line)["num_timesteps"]))
        except (ValueError, TypeError, KeyError):
            continue
    return steps


def best_so_far(output_dir: Path, metric: str) -> dict | None:
    """The ``best`` block of ``output_dir/best_model.json`` (the best evaluation before a
    resume; it may be newer than the checkpoint), or None when absent, unreadable or written
    without ``metric`` (an older format)."""
    path = Path(output_dir) / "best_model.json"
    if not path.is_file():
        return None
    try:
        best = json.loads(path.read_text())["best"]
        if not all(isinstance(best[k], (int, float)) for k in (metric, "terminated_episodes")):
            raise TypeError(f"its {metric} or terminated_episodes is not a number")
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        print(f"note: ignoring {path} ({exc!r}); the next evaluation writes a new best model",
              file=sys.stderr)  # fmt: skip
        return None
    return best
