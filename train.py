"""Train a stable-baselines3 agent on ``CapsuleSuspension-v0``: ``python train.py``.

A thin shell over :mod:`capsule_env.agents.learning.train` (read it top to bottom: its ``Args`` dataclass is the
command line), which an installed package runs as ``capsule-train`` or
``python -m capsule_env.agents.learning.train``.
"""

import sys

from capsule_env.agents.learning.train import main

if __name__ == "__main__":
    sys.exit(main())
