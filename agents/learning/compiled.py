"""``torch.compile`` of PPO's update: ``train.py --compile`` and ``bench_training.py --compile``.

PPO's update sets the pace of training on this env (the numba kernel steps millions of vehicles
a second; ``docs/benchmarks.md``), and each of its gradient steps is dozens of small torch
operations on a ``[64, 64]`` network. stable-baselines3's ``PPO.train`` calls
``policy.evaluate_actions(observations, actions)`` on every minibatch: :func:`compile_update`
replaces that method, on this policy object only, by its ``torch.compile`` d version (default
mode), so that the forward pass and, through AOTAutograd, its backward pass run as fused
kernels. What is not compiled: the rest of the loss (a few elementwise operations), the
gradient clip and the optimizer's step (``optimizer_kwargs=dict(fused=True)`` in the file's
``policy_kwargs`` fuses Adam's), and the rollouts' forward passes (one row per vehicle; not
measured compiled in ``benchmarks/``).

- The first update compiles: seconds, more with an empty Inductor cache (``bench_compile.py``).
- The numbers are not bit for bit eager's: fused kernels sum in another order, so the
  parameters after one update differ in the last bits, and a long run's trajectory drifts apart
  as any two runs with different rounding do (``tests/test_compiled.py`` bounds the difference
  after a few updates; ``docs/benchmarks.md`` compares the two over seeds).
- Nothing saved changes: the policy's parameters are the same tensors, ``model.save`` stores
  them as before, and a saved policy loads and runs without ``torch.compile``.
- PPO only (with or without ``--residual``): RecurrentPPO's ``evaluate_actions`` loops over
  sequences of varying length, and the off-policy algorithms' updates call other methods.
- Inductor needs a C++ compiler on the machine (it generates and builds C++ for the CPU):
  :func:`check_compile` looks for one before training starts.
- ``compiled_update`` in a saved policy's metadata says whether the process that saved it
  compiled its update; a resumed run may have trained partly one way, partly the other.
"""

from __future__ import annotations

from typing import Any

__all__ = ["COMPILABLE", "check_compile", "compile_update", "is_compiled"]

#: The algorithms whose update :func:`compile_update` compiles.
COMPILABLE = ("ppo",)


def check_compile(algo: str, compile_update_: bool) -> None:
    """``ValueError`` naming ``--compile`` when it is asked of an algorithm it does not serve,
    or on a machine where Inductor finds no C++ compiler."""
    if not compile_update_:
        return
    if algo not in COMPILABLE:
        raise ValueError(f"--compile serves {', '.join(COMPILABLE)} only (its update's "
                         f"evaluate_actions), not {algo}")  # fmt: skip
    from torch._inductor import cpp_builder  # Inductor's own search (config.cpp.cxx, $CXX)

    try:
        cpp_builder.get_cpp_compiler()
    except Exception as exc:  # InvalidCxxCompiler, or whatever a torch version raises
        raise ValueError(
            f"--compile needs a C++ compiler for torch.compile's CPU code, and "
            f"none was found ({str(exc).splitlines()[0]}); install g++ or set "
            "$CXX, or train without --compile"
        ) from None


def compile_update(model: Any) -> None:
    """Compile ``model.policy.evaluate_actions`` (what PPO's update calls on every minibatch),
    on this policy object only; the class and every other policy are untouched. The compiled
    function is bound to the policy as a method, so a copy of the policy (``copy.deepcopy``)
    calls it with its own parameters."""
    import types

    import torch

    policy = model.policy
    if is_compiled(model):
        return
    compiled = torch.compile(type(policy).evaluate_actions)
    policy.evaluate_actions = types.MethodType(compiled, policy)


def is_compiled(model: Any) -> bool:
    """Whether :func:`compile_update` compiled ``model``'s update."""
    return "evaluate_actions" in vars(model.policy)
