from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.manager.success import baseline_success, collided, proposed_success, task_success

TARGET = np.array([[0.0, 0.0, 0.0, 0.0, 0.0]])


@pytest.mark.parametrize(
    ("pos", "angle", "vel", "expected"),
    [
        ((0.04, 0.0), math.radians(4), (0.03, 0.03), True),  # speed 0.042 m/s
        ((0.06, 0.0), math.radians(4), (0.03, 0.03), False),  # 6 cm away
        ((0.04, 0.0), math.radians(6), (0.03, 0.03), False),  # 6 deg off
        ((0.04, 0.0), math.radians(4), (0.04, 0.04), False),  # speed 0.057 m/s
        ((0.0, 0.0), 2 * math.pi - 0.01, (0.0, 0.0), True),  # 0.01 rad off across the seam
    ],
)
def test_baseline_success(pos: tuple, angle: float, vel: tuple, expected: bool) -> None:
    got = baseline_success(TARGET, np.array([pos]), np.array([angle]), np.array([vel]))
    assert got.tolist() == [expected]


@pytest.mark.parametrize(
    ("subgoal", "robot_pos", "robot_vel", "expected"),
    [
        ((0.01, 0.0, math.radians(-4)), (0.0, 0.04), (0.0, 0.04), True),
        ((0.06, 0.0, 0.0), (0.0, 0.0), (0.0, 0.0), False),  # sub-goal 6 cm away
        ((0.0, 0.0, math.radians(6)), (0.0, 0.0), (0.0, 0.0), False),  # sub-goal 6 deg off
        ((0.0, 0.0, 0.0), (0.0, 0.06), (0.0, 0.0), False),  # robot 6 cm away
        ((0.0, 0.0, 0.0), (0.0, 0.0), (0.06, 0.0), False),  # robot too fast
    ],
)
def test_proposed_success(subgoal: tuple, robot_pos: tuple, robot_vel: tuple, expected: bool) -> None:
    subgoal5 = np.array([[*subgoal, 0.0, 0.0]])
    got = proposed_success(TARGET, subgoal5, np.array([robot_pos]), np.array([robot_vel]))
    assert got.tolist() == [expected]


def test_task_success_dispatch() -> None:
    # Robot and sub-goal on the target and still, but the robot faces backwards:
    # the baseline fails on heading, proposed and obstacle do not look at it.
    args = (TARGET, TARGET, np.zeros((1, 2)), np.array([math.pi]), np.zeros((1, 2)))
    assert task_success("baseline", *args).tolist() == [False]
    assert task_success("proposed", *args).tolist() == [True]
    assert task_success("obstacle", *args).tolist() == [True]
    with pytest.raises(ValueError, match="dribble"):
        task_success("dribble", *args)


def test_collided() -> None:
    robot = np.zeros((3, 2))
    obstacles = np.array(
        [
            [[0.19, 0.0], [2.0, 0.0]],  # first obstacle within 0.2 m
            [[0.0, 0.21], [0.0, -0.21]],  # both just outside
            [[3.0, 0.0], [0.1, 0.1]],  # second within (0.141 m)
        ]
    )
    assert collided(robot, obstacles).tolist() == [True, False, True]
    assert collided(robot, np.zeros((3, 0, 2))).tolist() == [False, False, False]
