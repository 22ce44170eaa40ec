"""``evaluate.py --floor``: the certified floor (:mod:`capsule_env.bounds`) of a setting's
episodes, checked before the run and added to its results as a ``floor`` block."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["add_floor", "check_floor_settings"]


def check_floor_settings(
    env_kwargs: Mapping[str, Any],
    settings: Sequence[str],
    seeds: Sequence[int] | np.ndarray,
    length_s: float,
    branch_nodes: int = 0,
) -> None:
    """Every setting's plant and the episode length must be ones the certified floor covers
    (:func:`capsule_env.bounds.check_floor`, which takes numpy integer seeds too), and the
    branching budget an integer >= 0; ValueError naming ``--floor`` (and the setting)."""
    from capsule_env.bounds import check_floor

    if isinstance(branch_nodes, bool) or not isinstance(branch_nodes, int) or branch_nodes < 0:
        raise ValueError(f"--floor NODES must be an integer >= 0 (node QPs of the branch and "
                         f"bound per episode; 0: no branching), got {branch_nodes!r}")  # fmt: skip

    for setting in settings:
        try:
            check_floor({**env_kwargs, "setting": setting}, seeds, length_s)
        except ValueError as exc:
            raise ValueError(f"--floor in the {setting} setting: {exc}") from None


def add_floor(
    block: dict,
    env_kwargs: Mapping[str, Any],
    seeds: Sequence[int] | np.ndarray,
    length_s: float,
    branch_nodes: int = 0,
) -> None:
    """Add the certified floor (:func:`capsule_env.bounds.certified_floor` on the same
    episodes, ``env_kwargs`` with the block's setting) to a setting's results as
    ``block["floor"]``: a row with ``wk_rms_body_acc_m_s2`` (the mean over episodes),
    per-episode values and the method, and ``floor_to_oracle`` (the floor over the oracle's
    Wk) when the block has an oracle row; ``branch_nodes`` > 0 adds the branch and bound over
    the stroke rate's sign (:mod:`capsule_env.bounds.branch`), the floor the larger of the two."""
    from capsule_env.bounds import certified_floor, floor_row

    row = floor_row(certified_floor(env_kwargs, seeds, length_s, branch_nodes=branch_nodes))
    oracle = block["controllers"].get("oracle")
    if oracle is not None and oracle["wk_rms_body_acc_m_s2"] > 0:
        row["floor_to_oracle"] = row["wk_rms_body_acc_m_s2"] / oracle["wk_rms_body_acc_m_s2"]
    block["floor"] = row
