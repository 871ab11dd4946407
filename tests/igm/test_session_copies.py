"""An IKSession copied, pickled or shared between threads answers as a fresh one, bit for
bit, on the "qp" engine too (its scratch configuration is lent per solve: a copy makes its
own, and a solve running while another holds it makes its own)."""

from __future__ import annotations

import copy
import pickle
import threading

import numpy as np

import qpik

A = {"ee": [0.45, 0.1, 0.45]}
B = {"ee": [0.3, -0.25, 0.55]}


def test_a_copied_or_pickled_session_answers_as_a_fresh_one_on_the_qp_engine():
    session = qpik.IKSession("panda")
    session.solve(A, seed=0, engine="qp")
    fresh = qpik.IKSession("panda").solve(B, seed=0, engine="qp")
    assert fresh.converged
    for twin in (copy.deepcopy(session), pickle.loads(pickle.dumps(session))):
        answer = twin.solve(B, seed=0, engine="qp")
        assert answer.converged and answer.iterations == fresh.iterations
        np.testing.assert_array_equal(answer.q, fresh.q)


def test_one_session_shared_by_two_threads_answers_as_it_does_alone():
    targets = [{"ee": [0.35 + 0.02 * k, 0.1 - 0.03 * k, 0.5]} for k in range(8)]
    alone = [qpik.IKSession("panda").solve(t, seed=k, engine="qp") for k, t in enumerate(targets)]
    shared = qpik.IKSession("panda")
    answers: dict = {}

    def run(offset: int) -> None:
        for k in range(offset, len(targets), 2):
            answers[k] = shared.solve(targets[k], seed=k, engine="qp")

    threads = [threading.Thread(target=run, args=(i,)) for i in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for k, reference in enumerate(alone):
        np.testing.assert_array_equal(answers[k].q, reference.q)
