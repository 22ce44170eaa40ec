"""Study files: what a sweep runs, checked before anything runs, expanded into trials.

A study file (YAML ``.yml``/``.yaml`` or JSON ``.json``) holds a mapping::

    name: ppo-lr                # the study's name (default: the file's stem)
    seed: 0                     # root of the derived training seeds (default 0)
    cpus_per_trial: 1           # Ray resources of one trial (default 1)
    trials:                     # one or more blocks
      - kind: train             # a kind of capsule_env.sweep.kinds.KINDS
        name: lr                # the block's label (default: <kind><index>)
        replicates: 2           # independent training seeds per grid point (seeded kinds)
        params:                 # fixed for every trial of the block
          total_timesteps: 2048
          hp.n_steps: 64
        grid:                   # every combination of these lists is one grid point
          hp.learning_rate: [0.001, 0.0003]

Each block expands to ``grid points x replicates`` trials (``seeds: [..]`` instead of
``replicates`` gives the seeds themselves). Trials of a seeded kind get a ``seed`` each, and
no two trials of a block share one: a derived seed is the first word of
``numpy.random.SeedSequence([study seed, block, grid point, replicate])``, so the trials'
random streams are independent (train.py derives every vehicle's stream from its seed with
``SeedSequence`` too), and a derived seed may not be any other trial's. Listed seeds must be
distinct within their block; two blocks may list the same seeds: a study that reproduces a
results table has one block per row, each with the seeds its runs used (``train.py --seed
S``, S = 0..4 for every algorithm).

Every error is a :class:`StudyError`: one line naming the file, the key and what is accepted.
"""

from __future__ import annotations

import itertools
import json
import math
import re
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.sweep.kinds import KINDS, Kind, json_ready

#: The most trials one grid point's ``replicates`` may ask for (issue 40: 1e6 made ``--check``
#: run for minutes); a study that needs more says so with several blocks.
MAX_REPLICATES = 1000
#: Seeds are numpy's and SB3's global seeds: 32 bits (train.py's ``--seed`` range).
MAX_SEED = 2**32 - 1


#: The top-level keys of a study file, with their meaning.
STUDY_KEYS = {
    "name": "the study's name (letters, digits, '-', '_', '.')",
    "seed": "root of the derived seeds (an integer >= 0)",
    "cpus_per_trial": "CPU cores Ray gives each trial (a number > 0)",
    "trials": "a list of blocks",
}
#: The keys of one block.
BLOCK_KEYS = {
    "kind": "the kind of trial",
    "name": "the block's label",
    "params": "a mapping of fixed parameters",
    "grid": "a mapping of parameter -> list of values",
    "replicates": f"independent seeds per grid point (an integer in 1..{MAX_REPLICATES})",
    "seeds": f"the seeds themselves (a list of distinct integers in 0..{MAX_SEED})",
}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class StudyError(ValueError):
    """A study file that cannot be run: the message is one line naming the key."""


@dataclass(frozen=True)
class Trial:
    """One trial: a kind, its parameters (fixed and grid values merged), its seed (``None`` for
    an unseeded kind) and its folder. ``point`` is the grid point's values (the figure's x
    labels); ``block`` the block's label."""

    name: str
    kind: str
    block: str
    params: dict[str, Any]
    point: dict[str, Any]
    seed: int | None
    dir: str

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (a Ray Tune config, ``study.json``)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Trial:
        return cls(**dict(data))


@dataclass(frozen=True)
class Study:
    """A checked study: its name, file, Ray resources and trials, in order."""

    name: str
    path: str
    cpus_per_trial: float
    trials: list[Trial] = field(default_factory=list)

    def blocks(self) -> list[str]:
        """The blocks' labels, in order."""
        return list(dict.fromkeys(t.block for t in self.trials))

    def fingerprint(self) -> list[dict[str, Any]]:
        """What identifies the study's trials (``study.json``: a restart must match it)."""
        return [{k: v for k, v in t.to_dict().items() if k != "dir"} for t in self.trials]


def derived_seed(root: int, block: int, point: int, replicate: int) -> int:
    """The seed of a trial: the first 31 bits of ``SeedSequence([root, block, point,
    replicate])``'s state (a valid seed for numpy, torch and train.py)."""
    state = np.random.SeedSequence([root, block, point, replicate]).generate_state(1)[0]
    return int(state) & 0x7FFFFFFF


def _unique_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's pairs as a dict; a key given twice is refused (JSON keeps the last)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise StudyError(f"duplicate key {key!r}: each key may appear once in a mapping")
        out[key] = value
    return out


def _yaml_loader() -> type:
    """PyYAML's safe loader, refusing a key given twice in one mapping (PyYAML keeps the
    last one silently); ``<<`` merges still override as YAML specifies."""
    import yaml

    class UniqueKeyLoader(yaml.SafeLoader):
        def construct_mapping(self, node: Any, deep: bool = False) -> dict:
            seen: set[Any] = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    duplicate = key in seen
                    seen.add(key)
                except TypeError:  # an unhashable key: the mapping's own error
                    continue
                if duplicate:
                    raise StudyError(
                        f"duplicate key {key!r} (line {key_node.start_mark.line + 1}): each key "
                        "may appear once in a mapping"
                    )
            return super().construct_mapping(node, deep)

    return UniqueKeyLoader


def read_study_file(path: str | Path) -> Any:
    """The content of a YAML or JSON study file; :class:`StudyError` for a missing, unreadable
    or malformed file, or one that gives a key twice in a mapping."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".yml", ".yaml", ".json"):
        raise StudyError(f"{path}: a study file ends in .yml, .yaml or .json, not {suffix!r}")
    try:
        text = path.read_text()
    except OSError as exc:
        raise StudyError(f"{path}: cannot read the study file ({exc.strerror})") from None
    try:
        if suffix == ".json":
            try:
                return json.loads(text, object_pairs_hook=_unique_pairs)
            except json.JSONDecodeError as exc:
                raise StudyError(f"{path}: not valid JSON: {exc}") from None
        return _read_yaml(text, path)
    except StudyError as exc:
        message = str(exc)
        where = message if message.startswith(str(path)) else f"{path}: {message}"
        raise StudyError(where) from None


def _read_yaml(text: str, path: Path) -> Any:
    try:
        import yaml
    except ImportError:
        raise StudyError(
            f"{path}: YAML study files need PyYAML (pip install 'capsule-env[scale]'), or "
            "write the study as JSON"
        ) from None
    try:
        return yaml.load(text, Loader=_yaml_loader())  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as exc:
        raise StudyError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None


def _int(value: Any, where: str, minimum: int, maximum: int | None = None) -> int:
    bad = isinstance(value, bool) or not isinstance(value, int) or value < minimum
    if bad or (maximum is not None and value > maximum):
        accepted = f">= {minimum}" if maximum is None else f"in {minimum}..{maximum}"
        raise StudyError(f"{where}: expected an integer {accepted}, got {value!r}")
    return value


def _mapping(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise StudyError(f"{where}: expected a mapping of names to values, got {value!r}")
    return dict(value)


def _unknown(keys: Any, accepted: Mapping[str, str], where: str) -> None:
    for key in keys:
        if key not in accepted:
            raise StudyError(
                f"{where}: unknown key {key!r}; accepted: {', '.join(accepted)}"
            )  # fmt: skip


def _kind(block: Mapping[str, Any], where: str) -> Kind:
    name = block.get("kind")
    if name not in KINDS:
        raise StudyError(f"{where}.kind: unknown kind {name!r}; accepted: {', '.join(KINDS)}")
    kind = KINDS[name]
    reason = kind.unavailable()
    if reason:
        raise StudyError(f"{where}.kind: kind {name!r} is not available here: {reason}")
    return kind


def _grid_points(grid: dict[str, Any], where: str) -> list[dict[str, Any]]:
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise StudyError(f"{where}.grid.{key}: expected a non-empty list of values, "
                             f"got {values!r}")  # fmt: skip
    keys = list(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*grid.values())]


def _seeds(block: Mapping[str, Any], kind: Kind, root: int, b: int, p: int, where: str) -> list:
    """The seeds of one grid point's trials (``[None]`` for an unseeded kind)."""
    if "replicates" in block and "seeds" in block:
        raise StudyError(f"{where}: give 'replicates' or 'seeds', not both")
    if not kind.seeded:
        for key in ("replicates", "seeds"):
            if key in block:
                raise StudyError(f"{where}.{key}: kind {kind.name!r} is deterministic (no "
                                 "seed); accepted keys: kind, name, params, grid")  # fmt: skip
        return [None]
    if "seeds" in block:
        seeds = block["seeds"]
        if not isinstance(seeds, list) or not seeds:
            raise StudyError(f"{where}.seeds: expected a non-empty list of integers in 0..{MAX_SEED}, "
                             f"got {seeds!r}")  # fmt: skip
        return [_int(s, f"{where}.seeds", 0, MAX_SEED) for s in seeds]
    replicates = _int(block.get("replicates", 1), f"{where}.replicates", 1, MAX_REPLICATES)
    return [derived_seed(root, b, p, r) for r in range(replicates)]


def _check_duplicate_seeds(trials: list[Trial], where: str) -> None:
    first: dict[int, str] = {}
    for t in trials:
        if t.seed is None:
            continue
        if t.seed in first:
            raise StudyError(
                f"{where}: trials {first[t.seed]} and {t.name} would share seed {t.seed} (and "
                "so their random streams); give each grid point its own seeds with "
                "'replicates' (derived, independent) instead of a list of 'seeds'"
            )
        first[t.seed] = t.name


def _study_header(data: Any, path: Path) -> tuple[str, int, float, list]:
    """The study's name, root seed, CPUs per trial and its list of blocks, checked."""
    where = str(path)
    if not isinstance(data, Mapping):
        raise StudyError(f"{where}: expected a mapping with the keys {', '.join(STUDY_KEYS)}, "
                         f"got {type(data).__name__}")  # fmt: skip
    _unknown(data, STUDY_KEYS, where)
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not _NAME.match(name):
        raise StudyError(f"{where}: name: expected {STUDY_KEYS['name']}, got {name!r}")
    root = _int(data.get("seed", 0), f"{where}: seed", 0)
    cpus = data.get("cpus_per_trial", 1)
    if isinstance(cpus, bool) or not isinstance(cpus, (int, float)) or not (
        math.isfinite(cpus) and cpus > 0
    ):  # fmt: skip
        raise StudyError(f"{where}: cpus_per_trial: expected a number > 0, got {cpus!r}")
    blocks = data.get("trials")
    if not isinstance(blocks, list) or not blocks:
        raise StudyError(f"{where}: trials: expected a non-empty list of blocks, each with the "
                         f"keys {', '.join(BLOCK_KEYS)}")  # fmt: skip
    return name, root, float(cpus), blocks


def _point_params(kind: Kind, fixed: dict, point: dict, bwhere: str) -> dict[str, Any]:
    """A grid point's parameters (the block's ``params`` and the point), checked by the kind
    and resolved."""
    params = {**fixed, **point}
    at = f"grid point {point}" if point else "params"
    for key, value in params.items():
        if not json_ready(value):
            raise StudyError(f"{bwhere} ({at}): {key}: expected numbers, strings, "
                             f"lists or mappings, got {value!r}")  # fmt: skip
    try:
        kind.check(params)
    except (ValueError, TypeError) as exc:
        raise StudyError(f"{bwhere} ({at}): {exc}") from None
    return kind.resolve(params)


def _block_trials(
    block: Any, b: int, root: int, labels: set[str], trials_dir: Path, where: str
) -> list[Trial]:
    """The trials of block ``b`` (its label is added to ``labels``, which must not hold it)."""
    bwhere = f"{where}: trials[{b}]"
    if not isinstance(block, Mapping):
        raise StudyError(f"{bwhere}: expected a mapping with the keys "
                         f"{', '.join(BLOCK_KEYS)}, got {block!r}")  # fmt: skip
    _unknown(block, BLOCK_KEYS, bwhere)
    kind = _kind(block, bwhere)
    label = block.get("name", f"{kind.name}{b}")
    if not isinstance(label, str) or not _NAME.match(label) or label in labels:
        raise StudyError(f"{bwhere}.name: expected a new label of letters, digits, '-', "
                         f"'_', '.', got {label!r}")  # fmt: skip
    labels.add(label)
    fixed = _mapping(block.get("params"), f"{bwhere}.params")
    grid = _mapping(block.get("grid"), f"{bwhere}.grid")
    for key in fixed.keys() & grid.keys():
        raise StudyError(f"{bwhere}: {key!r} is in both params and grid; keep it in one")
    for section, keys in (("params", fixed), ("grid", grid)):
        for key in keys:
            kind.check_key(key, f"{bwhere}.{section}")
    trials: list[Trial] = []
    for p, point in enumerate(_grid_points(grid, bwhere)):
        params = _point_params(kind, fixed, point, bwhere)
        for seed in _seeds(block, kind, root, b, p, bwhere):
            trial_name = f"{label}-{len(trials):03d}"
            trials.append(Trial(trial_name, kind.name, label, params, point, seed,
                                str(trials_dir / trial_name)))  # fmt: skip
    return trials


def build_study(data: Any, path: str | Path, out_dir: str | Path) -> Study:
    """Check a study file's content (``data``, as read from ``path``) and expand it into
    trials whose folders are ``<out_dir>/trials/<trial name>``. :class:`StudyError` names the
    first bad key and what it accepts."""
    path = Path(path)
    name, root, cpus, blocks = _study_header(data, path)
    trials_dir = Path(out_dir).resolve() / "trials"
    trials: list[Trial] = []
    labels: set[str] = set()
    derived: set[str] = set()
    for b, block in enumerate(blocks):
        block_trials = _block_trials(block, b, root, labels, trials_dir, str(path))
        _check_duplicate_seeds(block_trials, f"{path}: trials[{b}]")
        trials += block_trials
        if "seeds" not in block:  # replicates: derived seeds
            derived |= {t.name for t in block_trials}
    for t in trials:  # a derived seed is no other trial's, in any block
        if t.name in derived:
            _check_duplicate_seeds([t, *(o for o in trials if o is not t and o.seed == t.seed)],
                                   str(path))  # fmt: skip
    return Study(name, str(path.resolve()), cpus, trials)


def load_study(path: str | Path, out_dir: str | Path) -> Study:
    """Read, check and expand the study file ``path`` (see the module docstring)."""
    return build_study(read_study_file(path), path, out_dir)
