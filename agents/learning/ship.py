"""Ship a trained policy with the package: ``capsule_env/pretrained/NAME.{zip,vecnormalize.pkl,json}``.

    python -m capsule_env.agents.learning.ship runs/ppo-measured-seed1/best_model.zip ppo-measured \\
        --note "best of seeds 0, 1, 2 by the validation bank's Wk"

Copies the model and its normalisation statistics under the new name, and writes the json
(``train.py``'s metadata) with ``name`` set, the files' sizes and SHA-256 by role
(``digests``: ``model``, ``normaliser``; checked when the policy loads), where it came from (``shipped_from``) and why it was chosen
(``selection``). All three are saved in one atomic step
(:func:`capsule_env.agents.learning.policy_files.save_file_set`): a failed copy leaves the shipped files as they
were.
``evaluate.py`` lists every shipped policy by default.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from capsule_env.agents.learning.policy_files import (
    member_digests,
    readable_stem,
    save_file_set,
    sibling,
)
from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy

__all__ = ["ship_policy"]


def ship_policy(source_zip: str | Path, name: str, note: str = "",
                folder: str | Path = PRETRAINED_DIR) -> Path:  # fmt: skip
    """Copy the policy ``source_zip`` (with its ``.vecnormalize.pkl`` and ``.json``) to
    ``folder/name.*``; returns the new ``.zip``. Raises ``ValueError`` for a bad name or a
    policy that does not load (:meth:`SB3Policy.load`, which checks its files)."""
    if not name or any(c in name for c in "/\\. ") or name.startswith("-"):
        raise ValueError(f"name must be a plain file stem such as 'ppo-measured', got {name!r}")
    source_zip = Path(source_zip)
    SB3Policy.load(source_zip)  # refuses a missing, mixed or corrupt set
    stem = readable_stem(source_zip)
    meta = json.loads(sibling(stem, ".json").read_text())
    suffixes = (".zip", ".vecnormalize.pkl")
    data = {suffix: sibling(stem, suffix).read_bytes() for suffix in suffixes}
    target = Path(folder) / name

    def write(temp: Path) -> None:
        for suffix, blob in data.items():
            sibling(temp, suffix).write_bytes(blob)
        for old_format in ("files", "replay_buffer"):  # digests by file name (earlier versions)
            meta.pop(old_format, None)
        meta.update({"name": name, "digests": member_digests(temp),
                     "shipped_from": str(source_zip), "selection": note})  # fmt: skip
        sibling(temp, ".json").write_text(json.dumps(meta, indent=2, default=str))

    save_file_set(target, write)
    return sibling(target, ".zip")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("source", help="the policy's .zip (train.py's best_model.zip)")
    p.add_argument("name", help="the shipped name, e.g. ppo-measured")
    p.add_argument("--note", default="", help="why this policy (kept in the json)")
    args = p.parse_args(argv)
    try:
        path = ship_policy(args.source, args.name, args.note)
    except (ValueError, OSError) as exc:
        sys.exit(f"capsule_env.agents.learning.ship: error: {exc}")
    print(f"shipped {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
