"""``python -m capsule_env.bounds``: the certified floor of a setting's episodes, as JSON.

    OPENBLAS_NUM_THREADS=1 python -m capsule_env.bounds --setting sim --seed 1000 \\
        --episodes 10 --episode-length 1 --max-iterations 100
"""

from __future__ import annotations

import json
import sys

from capsule_env.bounds import DEFAULT_OPTIONS, MAX_FORCES, certified_floor
from capsule_env.common.cli import ArgumentParser, exits_on_interrupt, integer


@exits_on_interrupt("python -m capsule_env.bounds")
def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="python -m capsule_env.bounds", description=__doc__)
    p.add_argument("--setting", default="sim", help="env setting (sim; hils is refused)")
    p.add_argument("--seed", type=integer, default=1000, help="first episode seed (>= 0)")
    p.add_argument("--episodes", type=integer, default=10, help="episodes (>= 1)")
    p.add_argument("--episode-length", type=float, default=1.0,
                   help=f"s (default 1): at most {MAX_FORCES} force evaluations per episode, "
                        "about 2.2 s of the sim setting")  # fmt: skip
    iterations = DEFAULT_OPTIONS["max_iterations"]
    p.add_argument("--max-iterations", type=integer, default=iterations,
                   help=f"L-BFGS-B iterations per episode (default {iterations})")  # fmt: skip
    p.add_argument("--branch-nodes", type=integer, default=0,
                   help="also branch on the stroke rate's sign, at most this many node QPs "
                        "per episode (default 0: off)")  # fmt: skip
    args = p.parse_args(argv)
    if args.episodes < 1 or not 0 <= args.seed <= 2**63 - args.episodes:
        sys.exit(f"{p.prog}: error: --episodes must be >= 1 and --seed in [0, 2**63 - "
                 f"episodes], got {args.episodes}, {args.seed}")  # fmt: skip
    seeds = list(range(args.seed, args.seed + args.episodes))
    try:
        result = certified_floor({"setting": args.setting}, seeds, args.episode_length,
                                 max_iterations=args.max_iterations,
                                 branch_nodes=args.branch_nodes)  # fmt: skip
    except (ValueError, TypeError) as exc:
        sys.exit(f"{p.prog}: error: {exc}")
    print(json.dumps(result.summary(), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
