"""``python -m capsule_env.export NAME_OR_PATH --format onnx,c --out DIR`` (``capsule-export``).

Writes, for a shipped policy (``ppo-measured``, ...) or a saved one (``runs/x/best_model.zip``):
``NAME.onnx``, ``NAME.c`` and ``NAME.h`` (the formats asked for) and ``NAME.contract.json``
into ``DIR`` (created if needed), all in one atomic step (:mod:`capsule_env.export.artifacts`).
Bad input (an unknown name, a missing or bad file, an unknown format, an unwritable folder):
one line on stderr, exit status 1 (2 for the command line's syntax), nothing written.
"""

from __future__ import annotations

import argparse
import sys

from capsule_env.common.cli import ArgumentParser, exits_on_interrupt

__all__ = ["parse_args", "main"]

PROG = "capsule-export"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("policy", metavar="NAME_OR_PATH",
                   help="a shipped policy's name (ppo-measured, residual-ppo-mpc, ...) or a "
                        "saved policy's .zip (its .vecnormalize.pkl and .json beside it)")  # fmt: skip
    p.add_argument(
        "--format",
        default="onnx,c",
        help="comma-separated: onnx (NAME.onnx), c (NAME.c, NAME.h); default onnx,c",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="the folder to write into")
    p.add_argument(
        "--name",
        default=None,
        help="the files' stem (default: the policy's name from its metadata)",
    )
    return p.parse_args(argv)


@exits_on_interrupt("capsule-export")
def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from capsule_env.export.artifacts import export_policy

    try:
        written = export_policy(args.policy, args.out, args.format, args.name)
    except (ValueError, ImportError, OSError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 1
    for path in written.values():
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
