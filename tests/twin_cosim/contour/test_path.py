"""The programmed path: points along lines and arcs, and the distance to them."""

from __future__ import annotations

import math

import numpy as np

from twin_cosim.contour.path import Arc, Line, distance_to_path


def test_line_points_and_distance():
    line = Line((0.0, 0.0, 0.0), (0.03, 0.04, 0.0))
    assert math.isclose(line.length, 0.05)
    assert np.allclose(line.points(np.array([0.05])), [[0.03, 0.04, 0.0]])
    points = np.array([[0.0, 0.01, 0.0], [-0.003, -0.004, 0.0], [0.015, 0.02, 0.002]])
    assert np.allclose(line.distance(points), [0.006, 0.005, 0.002])


def test_arc_points_distance_inside_and_beyond_its_span():
    quarter = Arc((0.0, 0.0), 0.01, 0.0, math.pi / 2)  # CCW from +X to +Y
    assert np.allclose(quarter.end, (0.0, 0.01, 0.0), atol=1e-15)
    inside = np.array([[0.011 * math.cos(0.3), 0.011 * math.sin(0.3), 0.0]])
    assert np.allclose(quarter.distance(inside), 0.001)
    beyond = np.array([[-0.01, 0.0, 0.0]])  # on the circle, outside the arc: to the end point
    assert np.allclose(quarter.distance(beyond), math.hypot(0.01, 0.01))
    clockwise = Arc((0.0, 0.0), 0.01, 0.0, -math.pi / 2)  # CW from +X to -Y
    assert np.allclose(clockwise.end, (0.0, -0.01, 0.0), atol=1e-15)
    assert np.allclose(clockwise.distance(beyond), math.hypot(0.01, 0.01))
    full = Arc((0.0, 0.0), 0.01, 0.0, 2 * math.pi)
    assert np.allclose(full.distance(beyond), 0.0)


def test_distance_to_path_is_to_the_nearest_element():
    path = (Line((0.0, 0.0, 0.0), (0.01, 0.0, 0.0)), Line((0.01, 0.0, 0.0), (0.01, 0.01, 0.0)))
    points = np.array([[0.005, 0.001, 0.0], [0.0095, 0.005, 0.0]])
    assert np.allclose(distance_to_path(path, points), [0.001, 0.0005])
