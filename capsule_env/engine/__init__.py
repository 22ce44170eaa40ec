"""The env's engine, without Gym: its options (:mod:`~capsule_env.engine.config`), ``N`` vehicles
stepped by one compiled kernel (:mod:`~capsule_env.engine.batch`), the kernels and their
named structures (:mod:`~capsule_env.engine.kernels`, :mod:`~capsule_env.engine.env_kernel`,
:mod:`~capsule_env.engine.env_params`), the packed layouts (:mod:`~capsule_env.engine.layout`)
and every observable signal (:mod:`~capsule_env.engine.observations`). The Gym envs
(:mod:`capsule_env.envs`) and the oracle stand on it; it stands on the plant, the vehicles,
the dampers, the guideway and the envelope."""
