"""Review (session 14) of two unreviewed pieces.

The branch and bound's certificate (capsule_env.bounds.branch): ``BranchProblem.certify``
promises a valid bound at *any* multipliers (``z >= 0``); these tests hold it to that at
multipliers far from 1 in scale, against the same bound in exact rational arithmetic, and on
nodes holding trajectories the simulator runs.

The vectorised ``tanh`` (capsule_env.plant.glibc_tanh) outside the start-up probe's range, and
the lanes kernel with it forced off (the path of a machine where the probe refuses it)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from capsule_env.bounds.branch import BranchProblem
from capsule_env.bounds.lifted import closed_loop, lift_episode
from capsule_env.bounds.relaxation import FORCE_SCALE_N, damper_envelope, model_force_parts
from capsule_env.oracle.plant import OracleEpisodes
from capsule_env.plant.declared_lanes import VECTOR_TANH, lanes_step, plant_form
from capsule_env.plant.glibc_tanh import _tanh_both, matches_libm


@pytest.fixture(scope="module")
def leaf():
    """The maximum-current trajectory of seed 1000 over 0.1 s (the simulator's own: the lift
    closed with the plant damper), its problem, the leaf of its own signs and its J."""
    ep = OracleEpisodes({"setting": "sim"}, [1000], 0.1)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    current = np.array([ep.i_max])

    def law(x: float, v: float, step: int) -> float:
        d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), current)
        return float(d[0] + c[0])

    forces = closed_loop(lifted, law)
    problem = BranchProblem(lifted, damper_envelope(ep.code, p))
    v = lifted.affine(lifted.v_rows, forces)
    rows = problem.rows(np.where(v >= 0.0, 1, -1).astype(np.int8))
    y_w, z, _ = problem._sparse.solve(*rows)
    return problem, rows, y_w, np.maximum(z, 0.0), problem.ride(forces / FORCE_SCALE_N)


def _exact_bound(problem: BranchProblem, rows, y_w: np.ndarray, z: np.ndarray) -> Fraction:
    """``certify``'s formula in exact rational arithmetic (no rounding anywhere)."""
    gf, gv, h = rows
    n = problem.n
    fy = [Fraction(float(x)) for x in y_w]
    fz = [Fraction(float(x)) for x in z]

    def t_times(mat, vec: list[Fraction]) -> list[Fraction]:  # mat.T @ vec, exactly
        coo, out = mat.tocoo(), [Fraction(0)] * mat.shape[1]
        for r, c, val in zip(coo.row, coo.col, coo.data, strict=True):
            if vec[r] and val:
                out[c] += Fraction(float(val)) * vec[r]
        return out

    y_v = [-x for x in t_times(gv, fz)]
    r_f = t_times(gf, fz)
    a = problem.a_aug
    for j, yj in enumerate(y_v):
        if yj:
            for i in np.flatnonzero(a[j, :n]):
                r_f[i] -= Fraction(float(a[j, i])) * yj
    for k, yk in enumerate(fy):
        if yk:
            for i in np.flatnonzero(problem.wf[k]):
                r_f[i] -= Fraction(float(problem.wf[k, i])) * yk
    lin = -sum((yk * Fraction(float(c)) for yk, c in zip(fy, problem.wc, strict=True)),
               Fraction(0))  # fmt: skip
    lin -= sum((yj * Fraction(float(a[j, n])) for j, yj in enumerate(y_v)), Fraction(0))
    lin -= sum((zk * Fraction(float(hk)) for zk, hk in zip(fz, h, strict=True)), Fraction(0))
    lin -= sum((abs(r) * Fraction(float(b)) for r, b in zip(r_f, problem.f_abs, strict=True)),
               Fraction(0))  # fmt: skip
    quad = Fraction(problem.t) * sum((x * x for x in fy), Fraction(0)) / 4
    return Fraction(0) if lin <= 0 else lin * lin / (4 * quad)


def test_a_leafs_bound_does_not_depend_on_the_multipliers_scale(leaf) -> None:
    """The bound is invariant to scaling ``(y_w, z)`` by ``t > 0`` (module doc): at 2^-560
    ``|y_w|^2`` underflowed to 0 and the leaf that holds the trajectory was certified empty
    (``inf``); at 2^600 ``lin^2 / quad`` was ``inf / inf`` (NaN)."""
    problem, rows, y_w, z, ride = leaf
    base = problem.certify(*rows, y_w, z)
    assert 0.0 < base <= ride
    for scale in (2.0**-560, 2.0**-300, 2.0**300, 2.0**600):
        scaled = problem.certify(*rows, scale * y_w, scale * z)
        assert 0.0 < scaled <= ride
        assert scaled == pytest.approx(base, rel=1e-12)


def test_the_certified_bound_is_at_most_the_exact_bound_at_its_multipliers(leaf) -> None:
    """Weak duality holds for the exact value of ``S^2 / (4 Q)`` at the multipliers; the
    floating point sums must not round above it (the solver's multipliers and perturbed ones)."""
    problem, rows, y_w, z, ride = leaf
    rng = np.random.default_rng(14)
    cases = [(y_w, z)] + [(y_w * rng.uniform(1 - 1e-6, 1 + 1e-6, y_w.size),
                           z * rng.uniform(1 - 1e-6, 1 + 1e-6, z.size)) for _ in range(3)]  # fmt: skip
    for yy, zz in cases:
        exact = _exact_bound(problem, rows, yy, zz)
        got = problem.certify(*rows, yy, zz)
        assert math.isfinite(got) and 0.0 < got <= ride
        assert Fraction(got) <= exact
        assert got >= float(exact) * (1.0 - 1e-7)  # the rounding budget stays tiny


def test_non_finite_multipliers_certify_the_trivial_bound(leaf) -> None:
    """A solver that fails can return NaN multipliers: the bound was NaN (a NaN in the best-first
    heap, and a NaN floor); it is the trivial 0 (``J >= 0``)."""
    problem, rows, y_w, z, ride = leaf
    for bad_y, bad_z in ((y_w, np.where(np.arange(z.size) == 3, np.nan, z)),
                         (np.where(np.arange(y_w.size) == 0, np.inf, y_w), z)):  # fmt: skip
        assert problem.certify(*rows, bad_y, bad_z) == 0.0


@pytest.mark.parametrize("seed", [1000, 1001])
def test_leaves_of_real_trajectories_stay_below_their_simulated_j(seed: int) -> None:
    """0 A, maximum, random and on-off currents over 0.2 s: the compiled env's J (an
    independent computation) agrees with the lift's to 1e-13 relative, and the leaf fixing the
    trajectory's own signs, and nodes fixing a random part of them, are finite, certified
    below it."""
    from capsule_env import metrics
    from capsule_env.engine.layout import OUT_BODY_ACC

    ep = OracleEpisodes({"setting": "sim"}, [seed], 0.2)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    problem = BranchProblem(lifted, damper_envelope(ep.code, p))
    rng = np.random.default_rng(seed)
    for cur in (
        np.zeros(ep.n_steps),
        np.full(ep.n_steps, ep.i_max),
        rng.uniform(0.0, ep.i_max, ep.n_steps),
        rng.choice([0.0, ep.i_max], ep.n_steps),
    ):

        def law(x: float, v: float, step: int, cur: np.ndarray = cur) -> float:
            d, c = model_force_parts(ep.code, p, np.array([x]), np.array([v]), cur[[step]])
            return float(d[0] + c[0])

        forces = closed_loop(lifted, law)
        _, out = ep.run(np.array([0]), cur[None], substeps="env")
        j_env = float(metrics.wk_weighted_rms(out[0, :, OUT_BODY_ACC], ep.dt_s)) ** 2
        assert problem.ride(forces / FORCE_SCALE_N) == pytest.approx(j_env, rel=1e-13)
        sigma = np.where(lifted.affine(lifted.v_rows, forces) >= 0.0, 1, -1).astype(np.int8)
        for keep in (1.0, 0.9, 0.5):
            node = np.where(rng.random(sigma.size) < keep, sigma, 0).astype(np.int8)
            bound, _ = problem.node_bound(node)
            assert math.isfinite(bound) and 0.0 <= bound <= j_env


@pytest.mark.skipif(
    not matches_libm(), reason="glibc_tanh is this machine's tanh only where the probe says"
)
def test_glibc_tanh_is_the_librarys_outside_the_probes_range() -> None:
    """The probe draws magnitudes from 1e-20 to 30 (and 0, inf); the kernel can feed any
    number (a substep's path times sqrt(A p)). Subnormals, 1e-300..1e-20, 30..1e308, the
    largest double and quiet NaNs of both signs with payloads: the same bits. A signalling
    NaN is the one difference (the copy returns it as it is, the library quiets it):
    arithmetic never makes one, so the kernel never meets it."""
    rng = np.random.default_rng(14)
    tiny = np.finfo(float).tiny
    quiet = np.array([0x7FF8000000000001, 0xFFF8000000000123, 0x7FF8000000000000], np.uint64)
    xs = np.concatenate([rng.uniform(0.0, tiny, 20_000), [5e-324, np.nextafter(tiny, 0.0)],
                         10.0 ** rng.uniform(-300.0, -20.0, 50_000),
                         10.0 ** rng.uniform(math.log10(30.0), 308.0, 50_000),
                         [np.finfo(float).max, 2.0**1023, 709.8, 710.0]])  # fmt: skip
    xs = np.concatenate([xs, -xs, quiet.view(np.float64)])
    port, libm = np.empty_like(xs), np.empty_like(xs)
    _tanh_both(xs, port, libm)
    assert (port.view(np.int64) == libm.view(np.int64)).all()
    signalling = np.array([0x7FF0000000000001], np.uint64).view(np.float64)
    _tanh_both(signalling, port[:1], libm[:1])
    assert port[:1].view(np.uint64)[0] == 0x7FF0000000000001
    assert libm[:1].view(np.uint64)[0] == 0x7FF8000000000001


def test_the_lanes_kernel_without_vector_tanh_is_the_declared_plant_bit_for_bit() -> None:
    """The half-car on ``hils`` (Spencer's dampers: the split loops) with ``VECTOR_TANH``
    forced off (the C library's ``tanh`` lane by lane, what a machine where the probe refuses
    the copy runs) against ``declared_step``, 30 steps of currents over every bin."""
    from test_declared_lanes import _batch, _run

    from capsule_env.plant.declared import declared_step

    batch = _batch("half_car", "hils")
    code, n, form = batch.damper.code, batch.num_envs, plant_form(batch.plant)
    off = form - VECTOR_TANH if form // VECTOR_TANH % 2 == 1 else form
    assert off // VECTOR_TANH % 2 == 0
    command = np.random.default_rng(11).uniform(-0.1, 1.1, (30, n, batch.n_slots)) * batch.i_max

    def old(plant, x, c, route, dt, out):
        declared_step(code, 0, n, plant, x, c, route, dt, out)

    def fallback(plant, x, c, route, dt, out):
        lanes_step(code, off, 0, n, plant, x, c, route, dt, out)

    for (x_old, out_old), (x_new, out_new) in zip(_run(old, batch, command, 30),
                                                  _run(fallback, batch, command, 30), strict=True):  # fmt: skip
        assert np.isfinite(x_old).all() and np.abs(x_old).max() > 0.0
        assert (x_new == x_old).all() and (out_new == out_old).all()
