"""Compile an exported ``NAME.c`` with the system's C compiler and call it from Python.

For the parity tests, the latency benchmark and the HILS dry run: :func:`c_compiler` finds the
compiler (``$CC``, else ``cc``, ``gcc``, ``clang``), :func:`build_shared` compiles ``NAME.c`` into
a shared library with strict C99 flags (warnings are errors), :class:`CPolicy` calls its
functions through :mod:`ctypes`.
"""

from __future__ import annotations

import ctypes
import os
import shlex
import shutil
import subprocess
from pathlib import Path

import numpy as np

__all__ = ["C_FLAGS", "c_compiler", "build_shared", "CPolicy"]

#: Strict C99: what a rig's compiler would be given (``-lm`` for ``tanhf``).
C_FLAGS = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2")


def c_compiler() -> str | None:
    """The C compiler to use: ``$CC`` (its first word) if set, else the first of ``cc``,
    ``gcc``, ``clang`` on the PATH; None when there is none."""
    chosen = shlex.split(os.environ.get("CC", ""))
    candidates = chosen[:1] or ["cc", "gcc", "clang"]
    return next((path for c in candidates if (path := shutil.which(c))), None)


def build_shared(c_file: str | Path, out_dir: str | Path, flags: tuple[str, ...] = C_FLAGS) -> Path:
    """Compile ``c_file`` (its ``.h`` beside it) into ``out_dir/lib<stem>.so``; returns the
    library. ``RuntimeError`` with the compiler's message when it fails or none exists."""
    compiler = c_compiler()
    if compiler is None:
        raise RuntimeError("no C compiler found (set CC, or install cc, gcc or clang)")
    c_file = Path(c_file)
    library = Path(out_dir) / f"lib{c_file.stem}.so"
    cmd = [compiler, *flags, "-fPIC", "-shared", str(c_file), "-o", str(library), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if done.returncode != 0:
        raise RuntimeError(f"{shlex.join(cmd)} failed: {done.stderr.strip()[-2000:]}")
    return library


class CPolicy:
    """The functions of an exported policy's shared library (:func:`build_shared`)."""

    def __init__(self, library: str | Path, obs_size: int, action_size: int = 1) -> None:
        self.lib = ctypes.CDLL(str(Path(library).resolve()))
        self.obs_size, self.action_size = int(obs_size), int(action_size)
        floats = ctypes.POINTER(ctypes.c_float)
        self.lib.capsule_policy.argtypes = [floats, floats]
        self.lib.capsule_policy.restype = None
        self.has_control = hasattr(self.lib, "capsule_control")
        if self.has_control:
            self.lib.capsule_control.argtypes = [floats, floats]
            self.lib.capsule_control.restype = None
        self._action = np.zeros(self.action_size, dtype=np.float32)

    def _call(self, function: str, obs: np.ndarray) -> np.ndarray:
        rows = np.ascontiguousarray(np.atleast_2d(obs), dtype=np.float32)
        if rows.shape[1] != self.obs_size:
            raise ValueError(f"obs must have {self.obs_size} columns, got shape {rows.shape}")
        out = np.zeros((rows.shape[0], self.action_size), dtype=np.float32)
        call = getattr(self.lib, function)
        floats = ctypes.POINTER(ctypes.c_float)
        for k in range(rows.shape[0]):
            call(rows[k].ctypes.data_as(floats), out[k].ctypes.data_as(floats))
        return out

    def policy(self, obs: np.ndarray) -> np.ndarray:
        """``capsule_policy`` of each row of ``obs``: shape ``(n, action_size)``."""
        return self._call("capsule_policy", obs)

    def control(self, obs: np.ndarray) -> np.ndarray:
        """``capsule_control`` (a residual policy with its law in C) of each row of ``obs``."""
        if not self.has_control:
            raise ValueError("this library has no capsule_control (no residual law in C)")
        return self._call("capsule_control", obs)

    def combine(self, law_action: float, residual: float) -> float:
        """``capsule_combine`` (a residual policy)."""
        self.lib.capsule_combine.argtypes = [ctypes.c_float, ctypes.c_float]
        self.lib.capsule_combine.restype = ctypes.c_float
        return float(self.lib.capsule_combine(law_action, residual))
