"""The sensitivity study of the paper's Bi-exponential vs Bouc-Wen comparison (issue 27).

- :mod:`~capsule_env.sensitivity.points`: the factors, each point of each (what it changes
  and why its range), for the ``sim`` and ``hils`` tables;
- :mod:`~capsule_env.sensitivity.runner`: running a point (passive and both Skyhook pairs on
  the same evaluation-bank episodes) and its figures;
- :mod:`~capsule_env.sensitivity.policies`: the passive and on-off Skyhook policies it runs
  through the env's inverses;
- :mod:`~capsule_env.sensitivity.variable_step`: the closed loop on SciPy's variable-step
  plant (the solver factor).
- :mod:`~capsule_env.sensitivity.intervals`: the 95 % intervals over the episodes (t for a
  VRE, paired t for a gap, issue 43);
- :mod:`~capsule_env.sensitivity.measured_plant`: a plant damper identified from measured
  loops and scaled to the capsule (the measured-plant ``hils`` points, issue 43).

``experiments/paper_sensitivity.py`` is the thin script over them; docs/paper-reproduction.md
the page of its results.
"""
