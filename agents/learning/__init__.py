"""Learned controllers and what trains them (needs the ``rl`` extra): the SB3 algorithms
(:mod:`~capsule_env.agents.learning.algorithms`), a saved or in-memory policy
(:mod:`~capsule_env.agents.learning.sb3_policy`), residual policies on a classical law
(:mod:`~capsule_env.agents.learning.residual`), the training run and its command line
(:mod:`~capsule_env.agents.learning.training`, :mod:`~capsule_env.agents.learning.train`),
checkpoints and policy files (:mod:`~capsule_env.agents.learning.checkpoints`,
:mod:`~capsule_env.agents.learning.policy_files`), the RL-Zoo hyperparameters and the shipped
policies."""
