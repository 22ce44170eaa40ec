"""What every floor of the package shares, the way SB3 keeps a ``common/``: bad input turned into
one clear error (:mod:`~capsule_env.common.validation`), speed units
(:mod:`~capsule_env.common.units`), crash-safe files (:mod:`~capsule_env.common.safe_io`), the
command lines' shared parts (:mod:`~capsule_env.common.cli`) and the registries' discovery
(:mod:`~capsule_env.common.discover`). Nothing here imports another floor of the package."""
