"""Classical controllers: the laws and their signals (:mod:`~capsule_env.agents.controllers.law`,
:mod:`~capsule_env.agents.controllers.skyhook`, :mod:`~capsule_env.agents.controllers.two_state`),
the clipped LQR and its gain schedule (:mod:`~capsule_env.agents.controllers.lqr`,
:mod:`~capsule_env.agents.controllers.scheduled_lqr`), the preview LQ and the semi-active MPC
(:mod:`~capsule_env.agents.controllers.preview_lq`, :mod:`~capsule_env.agents.controllers.mpc`),
the registry by name (:mod:`~capsule_env.agents.controllers.classical`) and the tuned gains
(:mod:`~capsule_env.agents.controllers.tuned`, :mod:`~capsule_env.agents.controllers.tuning`)."""
