"""The capsule's operating envelope: EDS levitation against speed
(:mod:`~capsule_env.envelope.levitation`), trips from lift-off to cruise
(:mod:`~capsule_env.envelope.trips`), the env's envelope options
(:mod:`~capsule_env.envelope.options`), their per-step kernel
(:mod:`~capsule_env.envelope.kernel`) and the envelope page's report
(:mod:`~capsule_env.envelope.report`)."""
