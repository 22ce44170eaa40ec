"""A policy's deterministic action as one ONNX graph, through torch's exporter.

The graph takes ``obs`` (float32, ``(batch, n_obs)``, the env's raw observation) and gives
``action`` (float32, ``(batch, n_action)``): the ``VecNormalize`` normalisation (in double
precision, its clip included), SB3's own actor modules, the squashing or clipping SB3's
``predict`` applies and the clip to ``[-1, 1]`` (:mod:`capsule_env.export.network`); for a
residual policy, a row of ``obs`` holding a NaN or inf gets the residual 0 (the law alone, as
:class:`~capsule_env.agents.learning.residual.ResidualPolicy` acts). Needs the
``export`` extra (onnx, onnxscript: torch's exporter; onnxruntime to run the graph).
"""

from __future__ import annotations

import logging
import warnings
from typing import Any

import numpy as np

from capsule_env.export.network import DeterministicActor

__all__ = ["OPSET", "onnx_module", "onnx_bytes"]

#: The ONNX operator set the graph is written with (onnxruntime >= 1.17 runs it).
OPSET = 18


def onnx_module(actor: DeterministicActor, residual: bool = False) -> Any:
    """A ``torch.nn.Module`` whose forward is the deterministic action of ``actor``; with
    ``residual``, 0 on the rows of ``obs`` that hold a NaN or inf."""
    import torch

    class DeterministicAction(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.body = actor.modules
            norm = actor.normaliser
            self.normalise = norm is not None
            mean = norm.mean if norm is not None else np.zeros(actor.obs_size)
            std = norm.std if norm is not None else np.ones(actor.obs_size)
            self.clip = float(norm.clip) if norm is not None else 0.0
            self.register_buffer("mean", torch.tensor(mean, dtype=torch.float64))
            self.register_buffer("std", torch.tensor(std, dtype=torch.float64))
            self.register_buffer("low", torch.tensor(actor.low, dtype=torch.float32))
            self.register_buffer("high", torch.tensor(actor.high, dtype=torch.float32))

        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            x = obs
            if self.normalise:
                x = ((obs.double() - self.mean) / self.std).clamp(-self.clip, self.clip).float()
            a = self.body(x)
            if actor.tanh_output:
                a = torch.tanh(a)
            if actor.rescale:
                a = self.low + 0.5 * (a + 1.0) * (self.high - self.low)
            else:
                a = torch.minimum(torch.maximum(a, self.low), self.high)
            a = a.clamp(-1.0, 1.0)
            if residual:  # a row the network cannot read: the law alone
                a = torch.where(torch.isfinite(obs).all(dim=1, keepdim=True), a, 0.0)
            return a

    return DeterministicAction().eval()


def _check_installed() -> None:
    import importlib.util

    missing = [m for m in ("onnx", "onnxscript") if importlib.util.find_spec(m) is None]
    if missing:
        raise ValueError(f"--format onnx needs {' and '.join(missing)}: "
                         "pip install 'capsule-env[export]'")  # fmt: skip


def onnx_bytes(actor: DeterministicActor, residual: bool = False) -> bytes:
    """The serialised ONNX model of :func:`onnx_module` (opset :data:`OPSET`, a dynamic batch
    dimension), checked by ``onnx.checker``. ``ValueError`` when onnx or onnxscript is not
    installed."""
    _check_installed()
    import onnx
    import torch

    module = onnx_module(actor, residual)
    example = torch.zeros(1, actor.obs_size, dtype=torch.float32)
    batch = torch.export.Dim("batch", min=1)
    quiet = logging.getLogger("torch.onnx")
    level = quiet.level
    quiet.setLevel(logging.ERROR)  # the exporter logs each torchvision op it skips
    try:
        with warnings.catch_warnings(), torch.no_grad():
            warnings.simplefilter("ignore")
            program = torch.onnx.export(
                module, (example,), dynamo=True, input_names=["obs"], output_names=["action"],
                dynamic_shapes=({0: batch},), opset_version=OPSET, verbose=False,
            )  # fmt: skip
    finally:
        quiet.setLevel(level)
    proto = program.model_proto
    proto.producer_name = "capsule_env.export"
    onnx.checker.check_model(proto, full_check=True)
    return bytes(proto.SerializeToString())
