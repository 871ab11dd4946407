"""The compiled IGM's own rules (qpik.igm.kernels): scratch reuse leaves no trace, the
step moves only the chain's dofs, the restart draws follow the documented spread,
igm_solve is a pure function of its inputs (bitwise), and the damping law's smallest
singular value agrees with LAPACK's to the Gram matrix's roundoff."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_or_skip

import qpik
from qpik.igm import kernels as K
from qpik.model import KinematicChain

_GAMMA = 0x9E3779B97F4A7C15


def _advanced(seed: int, draws: int) -> int:
    """SplitMix64's state after ``draws`` draws: it advances by the golden gamma each."""
    return (seed + draws * _GAMMA) % 2**64


def _igm_inputs(model, frame, frame_type, target_q, restarts=5, max_iters=100):
    chain = KinematicChain.from_model(model, frame, frame_type)
    lower, upper = qpik.model.joint_limit_arrays(model)
    position, rotation = chain.pose(target_q)
    bounds = np.array([lower, upper, lower, upper])
    reach = chain.reach_bound(lower, upper).array
    options = np.array([1e-6, 1e-6, 1.0, 1.0, 0.2, 0.5, 0.05, 0.1, 0.3, 1e-6, 0.95])
    int_options = np.array([max_iters, restarts, 5, 0], dtype=np.int64)
    return chain, position, rotation, bounds, reach, options, int_options


def _run(chain, position, rotation, q0, bounds, reach, options, int_options, seed):
    n = int_options[0] + 1
    path = np.empty((2, n, q0.shape[0]))
    hist = np.empty((2, n, 3))
    info = np.empty(6, dtype=np.int64)
    state = np.array([seed], dtype=np.uint64)
    K.igm_solve(
        chain.arrays, position, rotation, True, q0.copy(), bounds, reach, options,
        int_options, state, np.inf, path, hist, info,
    )  # fmt: skip
    slot, length = info[3], info[4]
    return path[slot, length - 1].copy(), info.copy(), state[0]


def test_box_qp_scratch_reuse_leaves_no_trace():
    rng = np.random.default_rng(3)
    for trial in range(100):
        n = 1 + trial % 7
        M = rng.normal(size=(n + 1, n))
        H = M.T @ M + 1e-3 * np.eye(n)
        g = rng.normal(size=n) * 3
        lb, ub = -rng.uniform(0, 1, n), rng.uniform(0, 1, n)
        fresh = np.empty(n)
        K.box_qp(H, g, lb, ub, fresh, 4 * n + 20)
        dirty = K.box_qp_workspace(n)
        for array in dirty:
            array[...] = 7 if array.dtype.kind in "iu" else np.nan
        reused = np.empty(n)
        K.box_qp_with(H, g, lb, ub, reused, 4 * n + 20, dirty)
        assert reused.tobytes() == fresh.tobytes()


def _sigma_min(A, m, n, threshold=0.0):
    gram = np.empty((max(6, n), max(6, n)))
    return K.smallest_singular_value(np.ascontiguousarray(A), m, n, gram, threshold)


@pytest.mark.parametrize("rows", [3, 6, 9])
def test_smallest_singular_value_agrees_with_lapack(rows):
    """Laguerre's iteration on Cholesky factors (Gram matrices up to 6 x 6, Householder + QL
    where it does not settle) and Jacobi (larger, through this binding only): sigma_min^2 within a few eps |A|^2 of LAPACK's, also at (near-)rank
    deficiency, graded columns and repeated singular values; with a threshold, inf exactly
    when LAPACK's is clearly above it."""
    rng = np.random.default_rng(11)
    eps = np.finfo(float).eps
    for trial in range(600):
        n = 1 + trial % 9
        A = rng.normal(size=(rows, n)) * rng.uniform(0.01, 2.0, size=n)
        kind = trial % 6
        if kind == 1 and n > 1:
            A[:, 0] = A[:, -1] * 1e-3  # graded, dependent columns
        elif kind == 2 and n > 2:
            A[:, 2] = A[:, 0] - A[:, 1]  # rank deficient
        elif kind == 3:
            A *= 1e-5
        elif kind == 4:
            q, _ = np.linalg.qr(rng.normal(size=(max(rows, n), max(rows, n))))
            A = q[:rows, :n] * 0.7  # repeated singular values
        elif kind == 5:
            A[rows // 2] = 0.0  # a zero row: skipped
        kept = A[np.any(A != 0.0, axis=1)]
        s = np.linalg.svd(kept, compute_uv=False)
        expected = s[min(kept.shape) - 1]
        got = _sigma_min(A, rows, n)
        scale = max(s[0], 1e-300) ** 2
        assert abs(got**2 - expected**2) <= 64 * eps * scale, (trial, got, expected)
        for threshold in (0.05, 0.5):
            got_t = _sigma_min(A, rows, n, threshold)
            if expected > threshold * (1 + 1e-6):
                assert got_t == np.inf
            elif expected < threshold * (1 - 1e-6):
                assert got_t == got


def test_smallest_singular_value_of_non_finite_input_returns():
    for bad in (np.nan, np.inf, -np.inf, 1e300):
        for n in (1, 2, 4, 6, 7):
            A = np.ones((6, n))
            A[0, 0] = bad
            _sigma_min(A, 6, n)  # no hang, no crash; the value is unspecified


def test_igm_moves_only_the_chains_dofs():
    """Panda of example-robot-data: the fingers (two slides off the hand's chain) keep their
    start values in an attempt without restarts, and the answer meets the target."""
    model = load_or_skip("erd:panda")
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(0)
    target_q = configuration.random_q(rng)
    inputs = _igm_inputs(model, "panda_hand_tcp", "body", target_q, restarts=0)
    chain, position, rotation, bounds, reach, options, int_options = inputs
    assert chain.dofs.shape[0] == 7 < model.nv
    q0 = configuration.mid_q()
    q, info, _ = _run(chain, position, rotation, q0, bounds, reach, options, int_options, 1)
    off_chain = np.setdiff1d(np.arange(model.nv), chain.dofs)
    assert q[off_chain].tobytes() == q0[off_chain].tobytes()
    if info[0] == K.CONVERGED:
        p, _ = chain.pose(q)
        assert np.linalg.norm(p - position) <= 1e-6


def test_igm_is_a_pure_function_of_its_inputs():
    """Bitwise the same q, info and final RNG state whatever ran before (other targets,
    other seeds), and the rng state advanced by nq draws per restart."""
    model = qpik.load_robot("ur5e")
    configuration = qpik.Configuration(model)
    rng = np.random.default_rng(11)
    targets = [configuration.random_q(rng) for _ in range(4)]
    q0 = configuration.mid_q()
    first = []
    for seed, target_q in enumerate(targets):
        inputs = _igm_inputs(model, "ee", "site", target_q)
        chain, position, rotation, bounds, reach, options, int_options = inputs
        first.append(_run(chain, position, rotation, q0, bounds, reach, options, int_options, seed))
    for seed, target_q in reversed(list(enumerate(targets))):
        inputs = _igm_inputs(model, "ee", "site", target_q)
        chain, position, rotation, bounds, reach, options, int_options = inputs
        q, info, state = _run(
            chain, position, rotation, q0, bounds, reach, options, int_options, seed
        )
        q_first, info_first, state_first = first[seed]
        assert q.tobytes() == q_first.tobytes()
        assert (info == info_first).all()
        assert state == state_first
        assert int(state) == _advanced(seed, int(info[2]) * model.nq)


def test_restart_draws_alternate_between_the_central_box_and_all_of_it():
    """Odd restarts start in the central RESTART_SPREAD of the restart box, even ones
    anywhere in it. A 2R arm of unit links reaches its base only at q2 = +-pi, outside
    limits of +-1 rad: every attempt stalls, and the returned attempt starts at q0 or at one
    of the draws of that rule."""
    model = qpik.load_robot("planar_2r")
    chain = KinematicChain.from_model(model, "ee", "site")
    lower, upper = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    bounds = np.array([lower, upper, lower, upper])
    options = np.array([1e-9, 1e-9, 1.0, 1.0, 0.2, 0.5, 0.05, 0.1, 0.3, 1e-6, 0.95])
    restarts, seed = 6, 123
    state = np.array([seed], dtype=np.uint64)
    starts = [np.zeros(2)]
    for restart in range(1, restarts + 1):
        u = np.array([K.uniform(state) for _ in range(model.nq)])
        spread = 1.0 if restart % 2 == 0 else K.RESTART_SPREAD
        starts.append(lower + (upper - lower) * (0.5 + spread * (u - 0.5)))
        assert np.all(np.abs(starts[-1]) <= spread)
    int_options = np.array([3, restarts, 5, 0], dtype=np.int64)
    n = 4
    path, hist, info = np.empty((2, n, 2)), np.empty((2, n, 3)), np.empty(6, dtype=np.int64)
    rng_state = np.array([seed], dtype=np.uint64)
    K.igm_solve(
        chain.arrays, np.zeros(3), np.eye(3), False, np.zeros(2), bounds,
        np.array([0.0, 0.0, 0.0, 10.0]), options, int_options, rng_state, np.inf, path,
        hist, info,
    )  # fmt: skip
    assert info[0] != K.CONVERGED
    assert info[2] == restarts
    assert int(rng_state[0]) == _advanced(seed, restarts * model.nq)
    start = path[info[3], 0]
    assert any(start.tobytes() == s.tobytes() for s in starts)
