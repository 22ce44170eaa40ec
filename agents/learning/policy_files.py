"""A saved policy's files: their names, one atomic save of them all, and which complete set to
read (``train.py``'s ``best_model``, ``final_model`` and checkpoints, shipped policies).

A saved policy is a set of files with one stem: ``STEM.zip`` (the SB3 model),
``STEM.vecnormalize.pkl`` (its ``VecNormalize`` statistics), for SAC/TD3 checkpoints
``STEM.replay_buffer.pkl``, and ``STEM.json`` (metadata). :func:`sibling` names them: the stem
is the ``.zip``'s name without ``.zip`` only, so ``cur.v1.zip``'s metadata is ``cur.v1.json``.

The metadata binds its set **by content**: ``digests`` records the size and SHA-256 of each
other member by its role (:data:`ROLES`: ``model``, ``normaliser``, ``replay_buffer``), not by
its file name (:func:`member_digests`). The loaders check the files of the set they read
against it (:func:`digests_problem`), so a set copied or renamed whole (a backup folder,
``best_model.*`` renamed) loads, and a set mixed from two saves (one run's model with another's
metadata or statistics, whatever the names) is refused, naming the role and the files.
Metadata of earlier versions records ``files`` (and ``replay_buffer``) by the save's file names;
each such entry is checked as the member whose role its name's suffix gives.

:func:`save_file_set` replaces a set in one atomic step:

1. leftovers of an earlier killed save of the same stem are dealt with (:func:`clean_leftovers`);
2. the new files are written into a fresh hidden folder ``.STEM.<random>.tmp/`` and flushed to
   disk (a failure or a kill here leaves the previous set as it was; the folder is removed by
   the failing save or by the next save or start);
3. that folder is renamed to ``.STEM.commit/``: the **commit**, one ``rename``; from now on the
   new set is the saved one;
4. each file is hard-linked (copied where links are not allowed) to a hidden temporary name and
   renamed onto ``STEM.*``, the ``.json`` last;
5. ``.STEM.commit/`` is removed, its ``.json`` first.

Between 3 and 5 the public files may be mixed (some new, some old), but ``.STEM.commit/`` holds
the complete new set, and the loaders read from it (:func:`readable_stem`). A kill at any point
leaves the previous complete set or the new one readable, never a mix; the next save of the stem,
or ``train.py``'s start (:func:`clean_leftovers` of the folder), finishes steps 4 and 5 of a
committed save and removes the ``.tmp`` leftovers. Sets saved by earlier versions (plain
``STEM.*`` files, no commit folder) load as before.
"""

from __future__ import annotations

import errno
import json
import os
import re
import secrets
import shutil
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from typing import Any

from capsule_env.common.safe_io import file_digest

__all__ = [
    "shown_path",
    "SET_SUFFIXES",
    "sibling",
    "ROLES",
    "member_digests",
    "recorded_digests",
    "digests_problem",
    "commit_dir",
    "set_problem",
    "readable_stem",
    "save_file_set",
    "clean_leftovers",
]

#: The files of a saved policy, in the order they are published (the ``.json`` marks the set
#: complete and goes last).
SET_SUFFIXES = (".zip", ".vecnormalize.pkl", ".replay_buffer.pkl", ".json")
#: A temporary file or folder of :mod:`capsule_env.common.safe_io` or of :func:`save_file_set`.
_TEMP = re.compile(r"^\..+\.[0-9a-f]{8}\.tmp$")
_COMMIT = ".commit"
#: The members of a set that its metadata's ``digests`` bind, by role: the suffix of each one's
#: file (:func:`sibling`).
ROLES = {"model": ".zip", "normaliser": ".vecnormalize.pkl", "replay_buffer": ".replay_buffer.pkl"}


def shown_path(path: str | Path) -> str:
    """``path`` as results files record it: a file of the installed package (a shipped
    policy) as ``capsule_env/...``, the same on every machine; any other path as given."""
    import capsule_env

    package = Path(capsule_env.__file__).resolve().parent  # not this file's: agents/ in a checkout
    try:
        return str(Path(package.name) / Path(path).resolve().relative_to(package))
    except ValueError:
        return str(path)


def sibling(path: str | Path, suffix: str) -> Path:
    """The file ``suffix`` (``".json"``, ``".vecnormalize.pkl"``, ...) of the set of ``path``.

    ``path`` is the set's ``.zip`` or its stem; only a final ``.zip`` is taken off the name, so
    ``sibling("runs/cur.v1.zip", ".json")`` is ``runs/cur.v1.json`` (``Path.with_suffix``
    would give ``runs/cur.json``).
    """
    path = Path(path)
    name = path.name[: -len(".zip")] if path.name.endswith(".zip") else path.name
    return path.with_name(name + suffix)


def commit_dir(path: str | Path) -> Path:
    """``.STEM.commit/`` next to the set of ``path`` (its ``.zip`` or stem): the committed new
    set while a save publishes it (see the module docstring)."""
    stem = sibling(path, "")
    return stem.parent / f".{stem.name}{_COMMIT}"


def member_digests(stem: str | Path) -> dict[str, dict[str, int | str]]:
    """``{role: {"bytes": size, "sha256": hex}}`` of the members of the set ``stem`` (its
    ``.zip`` or stem) that exist (:data:`ROLES`): what a save records as its metadata's
    ``digests``, whatever names the set is later copied to."""
    files = {role: sibling(stem, suffix) for role, suffix in ROLES.items()}
    return {role: file_digest(path) for role, path in files.items() if path.is_file()}


def recorded_digests(meta: Mapping[str, Any]) -> dict[str, Any] | None:
    """The digests a set's metadata ``meta`` records, by role: its ``digests``, or (earlier
    versions) its ``files`` and ``replay_buffer`` keyed by file name, each under the role of its
    name's suffix (an unknown suffix under the name itself, which :func:`digests_problem`
    refuses). None when it records none (hand-made metadata)."""
    if isinstance(meta.get("digests"), dict):
        return dict(meta["digests"])
    if not isinstance(meta.get("files"), dict):
        return None
    by_name = {**meta["files"]}
    if isinstance(meta.get("replay_buffer"), dict):
        by_name.update(meta["replay_buffer"])
    roles = {}
    for name, digest in by_name.items():
        role = next((r for r, suffix in ROLES.items() if str(name).endswith(suffix)), name)
        roles[role] = digest
    return roles


def digests_problem(
    stem: str | Path, recorded: Mapping[str, Any], optional: Collection[str] = ("replay_buffer",)
) -> str | None:
    """Why the set ``stem`` (its ``.zip`` or stem) is not the one whose digests its metadata
    records (``recorded``, by role: :func:`recorded_digests`), or None. Each recorded role's
    file of this set (:data:`ROLES`) must have the recorded size and SHA-256 (a missing member
    of a role in ``optional`` is not checked: the caller decides about it), and each member
    present must be recorded (a replay buffer of another save next to a set saved without one
    is not that set's)."""
    meta_name = sibling(stem, ".json").name
    for role, suffix in ROLES.items():
        if role not in recorded and sibling(stem, suffix).is_file():
            return (f"its {role} {sibling(stem, suffix).name} is not a member {meta_name} "
                    "records (a file of another save?)")  # fmt: skip
    for role, expected in recorded.items():
        if role not in ROLES:
            return (f"{meta_name} records a member {role!r} that a policy set does not have "
                    f"(accepted: {', '.join(ROLES)})")  # fmt: skip
        path = sibling(stem, ROLES[role])
        if not path.is_file():
            if role in optional:
                continue
            return f"its {role} {path.name} is missing"
        actual = file_digest(path)
        if not isinstance(expected, Mapping) or any(
            actual[key] != expected.get(key) for key in ("bytes", "sha256")
        ):
            return (f"its {role} {path.name} is not the file {meta_name} records (size or "
                    "SHA-256 differs: a set mixed from different saves, a save that did not "
                    "finish, or a file changed afterwards)")  # fmt: skip
    return None


def set_problem(path: str | Path) -> str | None:
    """Why the set of ``path`` (its ``.zip`` or stem) is not one complete save, or None.

    Checked: the ``.json`` is a readable JSON object and every member whose size and SHA-256 it
    records by role (:func:`recorded_digests`) is there with that size and digest (a replay
    buffer only when present: old buffers are pruned), whatever the set's file names are
    (:func:`digests_problem`). A set without recorded digests (hand-made) is only checked for
    its ``.zip``.
    """
    meta_path, zip_path = sibling(path, ".json"), sibling(path, ".zip")
    if not meta_path.is_file():
        return f"no {meta_path.name}"
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        return f"{meta_path.name} is not readable JSON ({type(exc).__name__}: {exc})"
    if not isinstance(meta, dict):
        return f"{meta_path.name} is not a JSON object"
    recorded = recorded_digests(meta)
    if recorded is None:
        return None if zip_path.is_file() else f"no {zip_path.name}"
    return digests_problem(path, recorded)


def readable_stem(path: str | Path) -> Path:
    """The stem to read the set of ``path`` (its ``.zip`` or stem) from: the committed set in
    ``.STEM.commit/`` when a save of it was cut off after its commit and that set is complete
    (:func:`set_problem`), else the set's own stem. Reads only; writes nothing."""
    stem = sibling(path, "")
    committed = commit_dir(stem) / stem.name
    if committed.parent.is_dir() and set_problem(committed) is None:
        return committed
    return stem


def _fsync(path: Path) -> None:
    """Flush a file or a folder to disk (a folder: best effort, not every system allows it)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        if path.is_dir():
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not path.is_dir():
            raise
    finally:
        os.close(fd)


def _remove(path: Path) -> None:
    """Remove a file or a folder (a leftover); missing is fine."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _link_or_copy(source: Path, target: Path) -> None:
    """``target`` (new) with the content of ``source``: a hard link, or a flushed copy where
    the file system allows no hard links."""
    try:
        os.link(source, target)
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EXDEV, errno.EMLINK, errno.ENOTSUP, errno.EACCES):
            raise
        shutil.copyfile(source, target)
        _fsync(target)


def _publish(committed: Path, stem: Path) -> None:
    """Steps 4 and 5 of :func:`save_file_set`: the files of the complete set ``committed``
    (a folder ``.STEM.commit/``) onto ``STEM.*``, the ``.json`` last; then the folder goes,
    its ``.json`` first. Public files of the stem that the new set lacks are removed."""
    names = [stem.name + s for s in SET_SUFFIXES if (committed / (stem.name + s)).is_file()]
    for name in names:
        target = stem.parent / name
        if target.is_file() and os.path.samefile(committed / name, target):
            continue  # published before a kill (and a rename onto a link to itself is a no-op)
        temp = stem.parent / f".{name}.{secrets.token_hex(4)}.tmp"
        _link_or_copy(committed / name, temp)
        os.replace(temp, target)
    for suffix in SET_SUFFIXES:
        if stem.name + suffix not in names:
            (stem.parent / (stem.name + suffix)).unlink(missing_ok=True)
    _fsync(stem.parent)
    for name in reversed(names):  # the .json first: the folder no longer counts as a set
        (committed / name).unlink()
    _remove(committed)


def clean_leftovers(folder: str | Path, stem_name: str | None = None) -> list[Path]:
    """Finish or remove what killed saves left in ``folder`` (of the stem ``stem_name``, or of
    every stem): a complete ``.STEM.commit/`` is published (:func:`save_file_set`'s steps 4-5),
    an incomplete one (its publication had begun removing it) removed, and the hidden ``.tmp``
    files and folders removed. Returns the paths dealt with."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    done = []
    prefix = "." if stem_name is None else f".{stem_name}."
    for entry in sorted(folder.iterdir()):
        name = entry.name
        if not name.startswith(prefix):
            continue
        if name.endswith(_COMMIT) and entry.is_dir():
            stem = folder / name[1 : -len(_COMMIT)]
            if stem_name is not None and stem.name != stem_name:
                continue
            if set_problem(entry / stem.name) is None:
                _publish(entry, stem)
            else:
                _remove(entry)
            done.append(entry)
        elif _TEMP.match(name) and (stem_name is None or name.startswith(f".{stem_name}")):
            _remove(entry)
            done.append(entry)
    return done


def save_file_set(stem: str | Path, write: Callable[[Path], None]) -> None:
    """Replace the set ``STEM.*`` in one atomic step (the module docstring's steps 1-5).

    ``write(temp_stem)`` writes the new set's files as ``temp_stem + suffix`` (the
    :data:`SET_SUFFIXES`, the ``.json`` included) in a fresh hidden folder. An exception in it
    (a full disk) removes that folder and leaves the previous set as it was; an exception after
    the commit leaves the committed set in ``.STEM.commit/``, which the loaders read and the
    next save or start publishes.
    """
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(stem.parent, stem.name)
    staging = stem.parent / f".{stem.name}.{secrets.token_hex(4)}.tmp"
    staging.mkdir()
    try:
        write(staging / stem.name)
        if not (staging / (stem.name + ".json")).is_file():
            raise ValueError(f"a saved set needs its {stem.name}.json")
        for entry in staging.iterdir():
            _fsync(entry)
        _fsync(staging)
    except BaseException:
        _remove(staging)
        raise
    committed = commit_dir(stem)
    os.rename(staging, committed)  # the commit
    _fsync(stem.parent)
    _publish(committed, stem)
