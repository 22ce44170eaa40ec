"""``python -m capsule_env.datasets --task T --controller C --episodes N --seed S --out ROOT``
(``capsule-datasets``).

Records ``N`` episodes of the controller ``C`` (a classical law, a shipped policy or a policy's
``.zip``, or ``oracle``) on the registered task ``T``, episode ``k`` seeded ``S + k``, as a
Minari dataset ``capsule_env/T/NAME-v0`` under the new (or empty) folder ``ROOT``; prints the
dataset's folder and id. Read it with ``MINARI_DATASETS_PATH=ROOT`` and
``minari.load_dataset(ID)``. Bad input (an unknown task or controller, ``N < 1``, a seed out of
range, a ``ROOT`` that is a file or not empty, a missing extra): one line on stderr, exit
status 1 (2 for the command line's syntax), nothing written. Ctrl-C or SIGTERM: one line,
exit status 130, no dataset and no staging folder left.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from capsule_env.common.cli import ArgumentParser, integer

__all__ = ["parse_args", "main"]

PROG = "capsule-datasets"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[1] if __doc__ else None)
    p.add_argument("--task", required=True, metavar="ID",
                   help="a registered task: CapsuleSuspension-v0, CapsuleRide-v0, "
                        "CapsuleRidePreview-v0, CapsuleTrip-v0")  # fmt: skip
    p.add_argument("--controller", required=True, metavar="NAME_OR_PATH",
                   help="a classical law (mpc-biexp-meas, lqr-clipped-biexp-meas, ...), a "
                        "shipped policy (ppo-measured, residual-ppo-mpc, ...), a policy's .zip, "
                        "or oracle (the clairvoyant search: slow, minutes per 10 episodes)")  # fmt: skip
    p.add_argument("--episodes", type=integer, default=10, help="episodes (>= 1; default 10)")
    p.add_argument("--seed", type=integer, default=0,
                   help="episode k is the env seeded SEED + k (default 0)")  # fmt: skip
    p.add_argument(
        "--out",
        required=True,
        metavar="ROOT",
        help="a new or empty folder: the datasets root (MINARI_DATASETS_PATH)",
    )
    p.add_argument(
        "--episode-length",
        type=float,
        default=None,
        metavar="SECONDS",
        help="seconds per episode (default: the task's, 10)",
    )
    p.add_argument(
        "--name",
        default=None,
        help="the dataset's name (default: the controller's): capsule_env/T/NAME-v0",
    )
    return p.parse_args(argv)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


@contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM (a job scheduler's stop) raised as ``KeyboardInterrupt`` inside, as Ctrl-C is,
    so that the write's clean-up runs; the previous handler restored on exit."""
    try:
        before = signal.signal(signal.SIGTERM, _interrupt)
    except ValueError:  # not the main thread: leave the handler alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from capsule_env.datasets.record import record_dataset

    try:
        with _sigterm_interrupts():
            folder, ident = record_dataset(args.task, args.controller, args.episodes,
                                           args.seed, args.out, args.episode_length,
                                           args.name)  # fmt: skip
    except (ValueError, TypeError, ImportError, OSError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted: no dataset written to {args.out}", file=sys.stderr)
        return 130
    print(folder)
    print(ident)
    return 0


if __name__ == "__main__":
    sys.exit(main())
