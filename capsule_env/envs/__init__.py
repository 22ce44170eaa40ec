"""Gymnasium environments of capsule-env."""

from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv, CapsuleSuspensionVectorEnv

__all__ = ["CapsuleSuspensionEnv", "CapsuleSuspensionVectorEnv"]
