"""Evaluating controllers: episodes and the paper's metrics (:mod:`~capsule_env.evaluation.episodes`),
the condition an evaluation runs in (:mod:`~capsule_env.evaluation.condition`), the
``evaluate.py`` command (:mod:`~capsule_env.evaluation.evaluate`), its tables and key
(:mod:`~capsule_env.evaluation.tables`, :mod:`~capsule_env.evaluation.table_key`), the task
cards (:mod:`~capsule_env.evaluation.task_cards`) and the learned results' statistics
(:mod:`~capsule_env.evaluation.rl_statistics`)."""
