"""Crash-safe output files for the scripts (``train.py``, ``evaluate.py``, ``identify``).

- :class:`StagedFiles` writes a group of files to temporary names next to their targets and
  then renames them into place (``os.replace``) in the order they were staged, so a full disk
  or a kill during the writes leaves every previous file untouched, and a group (a model, its
  normalisation statistics, its metadata) moves together. :func:`atomic_write_text` is the
  one-file case.
- :func:`file_digest` / :func:`digest_mismatch`: sizes and SHA-256 of the files of a group,
  recorded in the group's metadata (the file renamed last, the "commit" marker) and checked by
  the loaders, which so detect a group mixed from two saves or truncated afterwards.
- :func:`append_line`: one line added to a log, or none (a failed write is cut off again).
- :func:`check_writable_dir` / :func:`check_writable_file`: an output path is checked before a
  long run starts, not after it; :func:`check_creatable_dir` checks a folder without making it.

Temporary files are named ``.<target name>.<random>.tmp`` in the target's folder (hidden, and
matching none of the scripts' own file patterns); they are removed when a write fails.
"""

from __future__ import annotations

import hashlib
import os
import secrets
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType

__all__ = [
    "StagedFiles",
    "atomic_write_text",
    "append_line",
    "file_digest",
    "digest_mismatch",
    "check_writable_dir",
    "check_creatable_dir",
    "check_writable_file",
]


def _new_temp(target: Path) -> Path:
    """Create an empty, uniquely named temporary file next to ``target`` (umask applies)."""
    while True:
        temp = target.parent / f".{target.name}.{secrets.token_hex(4)}.tmp"
        try:
            fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return temp


def _fsync(path: Path) -> None:
    with open(path, "rb") as fh:
        os.fsync(fh.fileno())


def _fsync_dir(folder: Path) -> None:
    """Make the renames in ``folder`` durable (best effort: not every platform allows it)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class StagedFiles:
    """A group of files written under temporary names, then renamed into place together.

    Use as a context manager: :meth:`temp_for` gives the temporary path to write a target to
    (hand it to any ``save(path)`` function), :meth:`write_bytes` / :meth:`write_text` write
    one directly. On a normal exit every temporary file is flushed to disk and only then
    renamed onto its target, in the order staged (stage the file that marks the group as
    complete last); on an exception the temporary files are removed and the targets are left
    as they were::

        with StagedFiles() as staged:
            model.save(staged.temp_for(stem.with_suffix(".zip")))
            staged.write_text(stem.with_suffix(".json"), text)
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []  # (target, temporary file)

    @property
    def staged(self) -> dict[Path, Path]:
        """``{target: temporary file}`` of the files staged so far."""
        return dict(self._staged)

    def temp_for(self, target: str | Path) -> Path:
        """A new temporary file (created empty) in ``target``'s folder, to write ``target`` to.

        The folder is created if needed.
        """
        target = Path(target)
        if any(t == target for t, _ in self._staged):
            raise ValueError(f"{target} is already staged")
        target.parent.mkdir(parents=True, exist_ok=True)
        temp = _new_temp(target)
        self._staged.append((target, temp))
        return temp

    def write_bytes(self, target: str | Path, data: bytes) -> Path:
        """Stage ``data`` as the new content of ``target``; returns the temporary file."""
        temp = self.temp_for(target)
        with open(temp, "wb") as fh:
            fh.write(data)
        return temp

    def write_text(self, target: str | Path, text: str) -> Path:
        """Stage ``text`` (UTF-8) as the new content of ``target``; returns the temporary file."""
        return self.write_bytes(target, text.encode("utf-8"))

    def commit(self) -> None:
        """Flush every temporary file to disk, then rename each onto its target in order."""
        folders = {target.parent for target, _ in self._staged}
        try:
            for _, temp in self._staged:
                _fsync(temp)
            while self._staged:
                target, temp = self._staged[0]
                os.replace(temp, target)
                self._staged.pop(0)
        except BaseException:
            self.discard()
            raise
        for folder in folders:
            _fsync_dir(folder)

    def discard(self) -> None:
        """Remove the temporary files not renamed yet (the targets stay as they were)."""
        for _, temp in self._staged:
            try:
                temp.unlink(missing_ok=True)
            except OSError:
                pass
        self._staged = []

    def __enter__(self) -> StagedFiles:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def atomic_write_text(path: str | Path, text: str) -> None:
    """Replace ``path`` by ``text`` (UTF-8) atomically: readers see the old or the new file,
    never a part of it; a failed write leaves the old file as it was."""
    with StagedFiles() as staged:
        staged.write_text(path, text)


def append_line(path: str | Path, line: str) -> None:
    """Add ``line`` (and a newline) to the end of the file ``path`` (created if needed), flushed
    to disk: the whole line, or, when the write fails (a full disk), nothing: the part written
    is cut off again before the error is raised, so the file keeps only whole lines."""
    data = (line.rstrip("\n") + "\n").encode("utf-8")
    with open(path, "ab") as fh:
        start = fh.seek(0, os.SEEK_END)
        try:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        except BaseException:
            try:
                fh.truncate(start)
            except OSError:
                pass
            raise


def file_digest(path: str | Path) -> dict[str, int | str]:
    """``{"bytes": size, "sha256": hex digest}`` of a file."""
    sha = hashlib.sha256()
    size = 0
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            sha.update(block)
            size += len(block)
    return {"bytes": size, "sha256": sha.hexdigest()}


def digest_mismatch(folder: str | Path, recorded: Mapping[str, Mapping]) -> str | None:
    """Why the files ``recorded`` (``{file name: file_digest}``) in ``folder`` do not match,
    or None when every one exists with the recorded size and SHA-256."""
    for name, expected in recorded.items():
        path = Path(folder) / name
        if not path.is_file():
            return f"{name} is missing"
        size = path.stat().st_size
        if size != expected.get("bytes"):
            return (
                f"{name} has {size} bytes, its metadata says {expected.get('bytes')} (a save "
                "that did not finish, or a file changed afterwards)"
            )
        if file_digest(path)["sha256"] != expected.get("sha256"):
            return (
                f"{name} is not the file its metadata was written with (sha256 differs: a "
                "save that did not finish, or a file changed afterwards)"
            )
    return None


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def check_writable_dir(path: str | Path, what: str) -> Path:
    """Create the folder ``path`` if needed and check that a file can be written in it.

    Raises ``ValueError`` naming ``what`` (e.g. ``"--output-dir"``) and the path otherwise.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = _new_temp(path / "write-test")
        probe.unlink()
    except OSError as exc:
        raise ValueError(
            f"{what} {str(path)!r} is not a writable folder ({_reason(exc)})"
        ) from None
    return path


def check_creatable_dir(path: str | Path, what: str) -> Path:
    """Check, making nothing, that the folder ``path`` is writable (:func:`check_writable_dir`,
    whose probe file is removed again) or, when it does not exist, can be made: its nearest
    existing ancestor is a writable folder. Raises ``ValueError`` naming ``what`` and the path
    otherwise. For the checks before a run, which then makes it (:func:`check_writable_dir`)
    once nothing can refuse it any more: a refused run leaves no empty folder behind."""
    path = Path(path)
    if path.exists():
        return check_writable_dir(path, what)
    ancestor = path.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ValueError(f"{what} {str(path)!r} is not a writable folder ({ancestor} is a file)")
    try:  # a file made and removed again, not os.access: root passes os.access on /proc
        _new_temp(ancestor / "write-test").unlink()
    except OSError as exc:
        raise ValueError(f"{what} {str(path)!r} is not a writable folder ({ancestor} is not "
                         f"writable: {_reason(exc)})") from None  # fmt: skip
    return path


def check_writable_file(path: str | Path, what: str) -> Path:
    """Check that the file ``path`` can be (re)written: not a folder or another non-regular
    file (a device, a pipe), its folder writable (created if needed; a symbolic link to a file
    is replaced by the new file, as every atomic write does). Raises ``ValueError`` naming
    ``what`` and the path otherwise."""
    if str(path) == "":
        raise ValueError(f"{what} is empty: give a file name")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a folder, not a file")
    if path.exists() and not path.is_file():  # a device, a pipe: replacing it would lose it
        raise ValueError(f"{what} {str(path)!r} is not a regular file")
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{what} {str(path)!r} is not writable")
    try:
        check_writable_dir(path.parent, "folder")
    except ValueError as exc:
        raise ValueError(f"{what} {str(path)!r}: {exc}") from None
    return path
