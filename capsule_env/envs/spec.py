"""The ``spec`` of an env whose episode length is an argument (``episode_length_s *
control_rate_hz``): ``gymnasium.make``'s spec with ``max_episode_steps`` filled in."""

from __future__ import annotations

import dataclasses
from typing import Any

from gymnasium.envs.registration import EnvSpec

__all__ = ["LengthSpec"]


def _spec_with_length(spec: EnvSpec | None, config: Any) -> EnvSpec | None:
    """The spec ``gymnasium.make`` gave, with ``max_episode_steps`` the env's own length when
    the registration leaves it open (it does: the length is ``episode_length_s *
    control_rate_hz``, an argument, so a fixed registered number would be wrong)."""
    if spec is None or spec.max_episode_steps is not None:
        return spec
    return dataclasses.replace(spec, max_episode_steps=config.max_episode_steps)


class LengthSpec:
    """The ``spec`` property of an env whose episode length is its own (``config``'s)."""

    config: Any
    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        return _spec_with_length(self._spec, self.config)

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        self._spec = value
