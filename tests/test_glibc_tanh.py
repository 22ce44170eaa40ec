""":func:`capsule_env.plant.glibc_tanh.glibc_tanh` against the C library's ``tanh`` (Python's
``math.tanh``), bit for bit, and the lanes kernel's choice of it
(:func:`capsule_env.plant.declared_lanes.plant_form`) only where they agree."""

from __future__ import annotations

import math

import numpy as np

from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.plant.declared_lanes import VECTOR_TANH, form_dims, plant_form
from capsule_env.plant.glibc_tanh import _tanh_both, matches_libm, probe_values


def _libm(xs: np.ndarray) -> np.ndarray:
    return np.array([math.tanh(x) for x in xs])


def test_the_lanes_kernel_vectorises_tanh_only_where_it_is_the_librarys():
    env = DeclaredVectorEnv(3, vehicle="half_car", setting="hils")
    form = plant_form(env.batch.plant)
    assert form_dims(form) == (4, 6, 2, 2)  # heave, pitch, two bogies; two slots, two contacts
    assert (form // VECTOR_TANH % 2 == 1) == matches_libm()
    xs = probe_values(2000, seed=1)
    port, libm = np.empty_like(xs), np.empty_like(xs)
    _tanh_both(xs, port, libm)
    assert (libm.view(np.int64) == _libm(xs).view(np.int64)).all()  # numba's call: Python's
    assert matches_libm() == bool((port.view(np.int64) == libm.view(np.int64)).all())


def test_glibc_tanh_is_the_librarys_tanh_bit_for_bit_where_the_probe_says():
    """On 600,000 arguments besides the probe's: equal wherever the probe found it equal (this
    machine: glibc 2.36 with FMA); elsewhere the probe's refusal is confirmed."""
    rng = np.random.default_rng(2026)
    xs = np.concatenate([rng.uniform(-25.0, 25.0, 200_000),
                         10.0 ** rng.uniform(-17.0, 1.5, 200_000),
                         -(10.0 ** rng.uniform(-17.0, 1.5, 200_000)),
                         [-0.0, np.nan, -np.inf, 5e-324, 2.0**-55, 2.0**-54]])  # fmt: skip
    port, libm = np.empty_like(xs), np.empty_like(xs)
    _tanh_both(xs, port, libm)
    same = port.view(np.int64) == libm.view(np.int64)
    assert (same[:-5].all() and np.isnan(port[-5]) and (port[-4:] == libm[-4:]).all()) == (
        matches_libm()
    )
    assert (libm[:1000] == _libm(xs[:1000])).all()
