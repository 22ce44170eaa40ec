"""Recorded episodes as a Minari dataset under a root folder of its own, written atomically.

Minari keeps its datasets under one root folder, ``MINARI_DATASETS_PATH`` (``~/.minari/datasets``
when unset), a dataset ``NAMESPACE/.../NAME-vN`` in the sub-folder of that path. Here the root
is given (``--out``) and must be new or empty: the dataset is built under a temporary root beside
it (``.<root name>.<random>.tmp``, Minari pointed at it for the call) and that folder is then
renamed onto the root in one step, so an interrupted or refused run leaves no partial dataset
(and never touches ``~/.minari``). Read it back with :func:`load_dataset`, or with Minari
itself: ``MINARI_DATASETS_PATH=ROOT`` and ``minari.load_dataset(dataset_id)``.

Storage: Minari's HDF5 format (``h5py``, the ``datasets`` extra). Observations and actions are
float32 as the env's spaces, rewards float64, the ``infos`` one float64 array per signal with
the reset's value first, as Minari's own ``DataCollector`` stores them.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.common.safe_io import check_creatable_dir
from capsule_env.datasets.rollouts import Episode

__all__ = ["NAMESPACE", "DATA_FORMAT", "dataset_id", "check_out", "datasets_root",
           "write_dataset", "load_dataset"]  # fmt: skip

#: The namespace of every dataset written here: ``capsule_env/<task id>/<name>-v0``.
NAMESPACE = "capsule_env"
#: Minari's storage format used (its default; ``h5py``).
DATA_FORMAT = "hdf5"
_ROOT_VARIABLE = "MINARI_DATASETS_PATH"


def dataset_id(task: str, name: str) -> str:
    """``capsule_env/<task>/<name>-v0`` (Minari's ``namespace/name-vN``)."""
    return f"{NAMESPACE}/{task}/{name}-v0"


def minari_module() -> Any:
    """``minari`` (with its HDF5 storage); ``ImportError`` naming the extra otherwise."""
    try:
        import h5py  # noqa: F401  (Minari's HDF5 storage)
        import minari
    except ImportError as exc:
        raise ImportError(f"datasets need minari with h5py: pip install "
                          f"'capsule-env[datasets]' ({exc})") from None  # fmt: skip
    return minari


def check_out(root: str | Path) -> Path:
    """The root folder ``root`` checked: new (its nearest existing ancestor writable) or an
    empty folder, where a folder can be made (a probe, removed again); a symbolic link to a
    folder stands for that folder (returned resolved). ``ValueError`` naming ``--out``
    otherwise; leaves nothing."""
    path = Path(root)
    if str(root) == "":
        raise ValueError("--out is empty: give a folder for the dataset")
    if path.is_symlink():  # the dataset goes where it points (renamed onto that folder)
        if not path.exists():
            raise ValueError(f"--out {str(path)!r} is a symbolic link to nothing "
                             f"({os.readlink(path)!r})")  # fmt: skip
        path = path.resolve()
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {str(path)!r} is a file, not a folder")
    if path.is_dir() and any(path.iterdir()):
        raise ValueError(f"--out {str(path)!r} is not empty: give a new or an empty folder (a "
                         "dataset root holds one dataset here)")  # fmt: skip
    path = check_creatable_dir(path, "--out")
    _probe_staging(path)
    return path


def _probe_staging(root: Path) -> None:
    """Make and remove a folder where :func:`write_dataset` stages (beside ``root``, or in
    its nearest existing ancestor): a place the permission bits allow but the file system
    refuses (``/proc``, a read-only mount seen by root) is refused before the run, naming
    ``--out``."""
    parent = root.absolute().parent
    while not parent.exists():
        parent = parent.parent
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".capsule-datasets.", suffix=".probe", dir=parent))
    except OSError as exc:
        raise ValueError(f"--out {str(root)!r}: cannot make a folder in {str(parent)!r} "
                         f"({exc.strerror or exc})") from None  # fmt: skip


@contextmanager
def datasets_root(root: str | Path) -> Iterator[Path]:
    """Minari's datasets root (``MINARI_DATASETS_PATH``) set to ``root`` inside, restored on
    exit."""
    before = os.environ.get(_ROOT_VARIABLE)
    os.environ[_ROOT_VARIABLE] = str(Path(root).absolute())
    try:
        yield Path(root)
    finally:
        if before is None:
            os.environ.pop(_ROOT_VARIABLE, None)
        else:
            os.environ[_ROOT_VARIABLE] = before


def _buffers(episodes: Sequence[Episode]) -> list[Any]:
    from minari.data_collector import EpisodeBuffer

    return [EpisodeBuffer(id=k, seed=e.seed, observations=e.observations, actions=e.actions,
                          rewards=e.rewards, terminations=e.terminations,
                          truncations=e.truncations, infos=dict(e.infos))
            for k, e in enumerate(episodes)]  # fmt: skip


def _json_ready(value: Any) -> Any:
    """``value`` through JSON (NumPy scalars and arrays as numbers and lists)."""

    def default(obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            return obj.tolist()
        if isinstance(obj, np.generic):
            return obj.item()
        raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")

    return json.loads(json.dumps(value, default=default))


def _create(ident: str, episodes: Sequence[Episode], env: Any, eval_spec: Any,
            description: dict[str, Any]) -> None:  # fmt: skip
    """Minari's own writer, in the current root (:func:`datasets_root`)."""
    import capsule_env

    minari = minari_module()
    with warnings.catch_warnings():  # Minari asks for an author's e-mail and a permalink
        warnings.filterwarnings("ignore", message=r".*is set to None", category=UserWarning)
        dataset = minari.create_dataset_from_buffers(
            dataset_id=ident, buffer=_buffers(episodes), env=env, eval_env=eval_spec,
            algorithm_name=str(description["controller"]["name"]), author="capsule-env",
            description=str(description["summary"]), data_format=DATA_FORMAT,
            requirements=[f"capsule-env=={capsule_env.__version__}"],
        )  # fmt: skip
    dataset.storage.update_metadata({"capsule_env": _json_ready(description)})


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_dataset(root: str | Path, ident: str, episodes: Sequence[Episode], env: Any,
                  eval_spec: Any, description: dict[str, Any]) -> Path:  # fmt: skip
    """Write ``episodes`` as the dataset ``ident`` under the new root ``root`` (module
    docstring): ``env`` the env they were recorded in (its spec is stored for
    ``recover_environment()``), ``eval_spec`` the spec of the env to evaluate in
    (``recover_environment(eval_env=True)``), ``description`` the ``capsule_env`` block of the
    metadata (``summary``: Minari's one-line description). Returns the dataset's folder."""
    final = check_out(root).absolute()
    final.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent))
    try:
        staging.chmod(0o777 & ~_umask())  # mkdtemp's 0o700 is for the staging only
        with datasets_root(staging):
            _create(ident, episodes, env, eval_spec, description)
        check_out(final)
        if final.is_dir():
            final.rmdir()
        os.replace(staging, final)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return final / ident


def load_dataset(root: str | Path, ident: str) -> Any:
    """The dataset ``ident`` under the root ``root`` (``minari.load_dataset`` with
    ``MINARI_DATASETS_PATH`` set to it for the call)."""
    minari = minari_module()
    with datasets_root(root):
        return minari.load_dataset(ident)
