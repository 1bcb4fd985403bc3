"""Fixtures shared by the test modules: the default scene's models and its grasp configurations."""

from __future__ import annotations

import pytest

from pickplace.grasping.configurations import GraspConfigurations, solve_grasp_configurations
from pickplace.robot import model


@pytest.fixture(scope="module")
def robot() -> model.Robot:
    """The default scene, built once per test module."""
    return model.build()


@pytest.fixture(scope="module")
def configs(robot: model.Robot) -> GraspConfigurations:
    """The four targets of the default scene solved to joint configurations."""
    return solve_grasp_configurations(robot)
