"""What differs between the Gymnasium versions capsule-env supports (``gymnasium>=1.0``).

- ``gymnasium.vector.AutoresetMode`` appeared in Gymnasium 1.1. On 1.0 this module defines an
  enum with the same members and values (``NEXT_STEP = "NextStep"``, ``SAME_STEP =
  "SameStep"``, ``DISABLED = "Disabled"``), so the native vector env offers the three modes on
  every supported version; on 1.1 and later :data:`AutoresetMode` *is* Gymnasium's enum.

:func:`check_autoreset_mode` turns what a user passes (the enum member, its value or its name,
from either enum) into a member of :data:`AutoresetMode`.
"""

from __future__ import annotations

from enum import Enum
from typing import Any

__all__ = ["AutoresetMode", "GYMNASIUM_HAS_AUTORESET_MODE", "check_autoreset_mode"]

try:
    from gymnasium.vector import AutoresetMode

    #: Whether the installed Gymnasium defines ``AutoresetMode`` itself (1.1 and later).
    GYMNASIUM_HAS_AUTORESET_MODE = True
except ImportError:  # gymnasium 1.0

    class AutoresetMode(Enum):  # type: ignore[no-redef]
        """Gymnasium 1.1's ``AutoresetMode`` for Gymnasium 1.0 (same members, same values)."""

        NEXT_STEP = "NextStep"
        SAME_STEP = "SameStep"
        DISABLED = "Disabled"

    GYMNASIUM_HAS_AUTORESET_MODE = False


def check_autoreset_mode(value: Any) -> AutoresetMode:
    """``value`` as an :data:`AutoresetMode` member: a member (of Gymnasium's enum or of this
    module's), its value (``"NextStep"``, ``"SameStep"``, ``"Disabled"``) or its name
    (``"NEXT_STEP"``, ``"SAME_STEP"``, ``"DISABLED"``, any case). Anything else raises
    ``ValueError`` (``TypeError`` for a non-string) naming ``autoreset_mode`` and the accepted
    values."""
    accepted = ", ".join(f"AutoresetMode.{m.name} ({m.value!r})" for m in AutoresetMode)
    if isinstance(value, Enum):
        value = value.value
    if not isinstance(value, str):
        raise TypeError(
            f"autoreset_mode must be a gymnasium.vector.AutoresetMode or its string value "
            f"({accepted}), got {value!r} ({type(value).__name__})"
        )
    for member in AutoresetMode:
        if value == member.value or value.upper() == member.name:
            return member
    raise ValueError(f"unknown autoreset_mode {value!r}; accepted: {accepted}")
