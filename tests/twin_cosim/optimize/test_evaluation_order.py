"""The order of a generation under early stopping: the likeliest best first."""

from __future__ import annotations

import numpy as np

from twin_cosim.optimize.evaluation_order import NEIGHBOURS, likeliest_best_first


def test_without_evaluations_the_order_is_the_one_asked_in():
    assert likeliest_best_first(np.zeros((4, 2)), np.empty((0, 2)), np.empty(0)).tolist() == [
        0,
        1,
        2,
        3,
    ]


def test_candidates_near_good_evaluations_go_first():
    # a valley at the origin: fitness grows with the distance from it
    rng = np.random.default_rng(0)
    evaluated = rng.uniform(-1.0, 1.0, size=(200, 2))
    fitness = 1.0 + np.linalg.norm(evaluated, axis=1)
    candidates = np.array([[0.9, 0.9], [0.05, 0.0], [-0.5, 0.4], [0.0, -0.2]])
    order = likeliest_best_first(candidates, evaluated, fitness)
    assert order.tolist() == [1, 3, 2, 0]


def test_equal_predictions_keep_the_order_asked_in():
    evaluated = np.zeros((NEIGHBOURS, 3))
    order = likeliest_best_first(np.ones((5, 3)), evaluated, np.full(NEIGHBOURS, 2.0))
    assert order.tolist() == [0, 1, 2, 3, 4]
