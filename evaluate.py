"""Reproduce the paper's comparison and compare any controller with it: ``python evaluate.py``.

A thin shell over :mod:`capsule_env.evaluation.evaluate` (read it top to bottom), which an installed
package runs as ``capsule-evaluate`` or ``python -m capsule_env.evaluation.evaluate``.
"""

import sys

from capsule_env.evaluation.evaluate import main

if __name__ == "__main__":
    sys.exit(main())
