"""The starts of the clairvoyant search (:func:`capsule_env.oracle.clairvoyant_bound`): named
ones, constant currents, given current arrays, and candidates (e.g. each evaluated
controller's applied currents), of which each episode is searched from the best few."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from capsule_env.oracle.plant import OracleEpisodes

__all__ = ["DEFAULT_STARTS", "START_NAMES", "candidate_starts", "named_starts", "searched_starts"]

#: Named starts of the search: zero current, 10 %, half and full ``i_max``, on-off Skyhook on
#: the true state (:meth:`OracleEpisodes.skyhook_currents`), uniform random currents.
START_NAMES = ("zero", "low", "mid", "max", "skyhook", "random")
_START_LEVELS = {"zero": 0.0, "low": 0.1, "mid": 0.5, "max": 1.0}
#: The starts used unless told otherwise: the two best measured (low currents) and a
#: Skyhook-like one, whose local optimum shows how much the search depends on its start.
DEFAULT_STARTS: tuple[str, ...] = ("zero", "low", "skyhook")


def _named_start(episodes: OracleEpisodes, j: int, start: str, random_seed: int) -> np.ndarray:
    """The (E, T) currents of start name ``start`` (``starts[j]``)."""
    if start not in START_NAMES:
        raise ValueError(f"starts[{j}]: unknown start {start!r}; accepted: {START_NAMES}")
    e, t, i_max = episodes.n_episodes, episodes.n_steps, episodes.i_max
    if start == "skyhook":
        return episodes.skyhook_currents()
    if start == "random":
        rows = [
            np.random.default_rng([random_seed, s]).uniform(0.0, i_max, t) for s in episodes.seeds
        ]
        return np.stack(rows)
    return np.full((e, t), _START_LEVELS[start] * i_max)


def _array_start(episodes: OracleEpisodes, where: str, start: Any) -> np.ndarray:
    """The (E, T) currents of a given current array ``start`` (named ``where`` in errors,
    e.g. ``starts[2]``), checked."""
    e, t, i_max = episodes.n_episodes, episodes.n_steps, episodes.i_max
    if isinstance(start, (bool, np.bool_)) or not isinstance(start, (Sequence, np.ndarray)):
        raise TypeError(
            f"{where} must be a start name, a number (a constant current, A) or a "
            f"current array, got {start!r} ({type(start).__name__})"
        )
    try:
        a = np.asarray(start, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{where}: a current array must hold numbers (A)") from None
    if a.shape not in ((t,), (e, t)):
        raise ValueError(
            f"{where}: a current array must have shape ({t},) or ({e}, {t}) "
            f"(episodes, steps), got {a.shape}"
        )
    if not np.all(np.isfinite(a)) or a.min() < 0.0 or a.max() > i_max:
        raise ValueError(f"{where}: currents must be finite and in [0, {i_max}] A")
    return np.broadcast_to(a, (e, t)).copy()


def named_starts(
    episodes: OracleEpisodes, starts: Sequence[Any], random_seed: int
) -> tuple[list[str], np.ndarray]:
    """The named or given starts as an (S, E, T) array of currents, and their names."""
    if isinstance(starts, (str, np.ndarray)) or not isinstance(starts, Sequence) or not starts:
        kind = ValueError if isinstance(starts, Sequence) and not starts else TypeError
        raise kind(
            f"starts must be a non-empty sequence of start names {START_NAMES}, numbers "
            f"(constant currents, A) or current arrays, got {starts!r}"
        )
    e, t, i_max = episodes.n_episodes, episodes.n_steps, episodes.i_max
    names, arrays = [], []
    for j, start in enumerate(starts):
        if isinstance(start, str):
            names.append(start)
            arrays.append(_named_start(episodes, j, start, random_seed))
        elif isinstance(start, (int, float, np.integer, np.floating)) and not isinstance(
            start, bool
        ):
            level = float(start)
            if not 0.0 <= level <= i_max:
                raise ValueError(f"starts[{j}]: a constant current must be in [0, {i_max}] A")
            names.append(f"constant:{level:g}")
            arrays.append(np.full((e, t), level))
        else:
            arrays.append(_array_start(episodes, f"starts[{j}]", start))
            names.append(f"given:{j}")
    return names, np.stack(arrays)


def candidate_starts(
    episodes: OracleEpisodes, candidates: Any, taken: Sequence[str]
) -> tuple[list[str], np.ndarray]:
    """The candidate sequences as a (C, E, T) array of currents, and their names (checked:
    strings, none of them a start's name ``taken``)."""
    shape = (0, episodes.n_episodes, episodes.n_steps)
    if candidates is None:
        return [], np.zeros(shape)
    if not isinstance(candidates, Mapping):
        raise TypeError(
            f"candidates must be a mapping of names to current arrays, got {candidates!r}"
        )
    names, arrays = [], []
    for name, sequence in candidates.items():
        if not isinstance(name, str) or not name or name in taken:
            raise ValueError(
                f"candidates: a name must be a non-empty string other than the starts' "
                f"names {tuple(taken)}, got {name!r}"
            )
        names.append(name)
        arrays.append(_array_start(episodes, f"candidates[{name!r}]", sequence))
    return names, np.stack(arrays) if arrays else np.zeros(shape)


def searched_starts(start_wk: np.ndarray, n_starts: int, per_episode: int) -> np.ndarray:
    """(E, S) which starts each episode is searched from: the first ``n_starts`` (the
    ``starts``) always, and of the rest (the candidates) the ``per_episode`` of lowest own Wk
    in that episode (``start_wk`` (E, S))."""
    searched = np.zeros(start_wk.shape, dtype=bool)
    searched[:, :n_starts] = True
    order = np.argsort(start_wk[:, n_starts:], axis=1, kind="stable")[:, :per_episode]
    np.put_along_axis(searched[:, n_starts:], order, True, axis=1)
    return searched
