"""Gymnasium environments of pickplace (``pip install 'pickplace[gym]'``): registered when this package is imported.

======================================  ===========================================================================
id                                      one step
======================================  ===========================================================================
``pickplace/PickPlace-v0``              a whole pick and place with the grasp (and place pose) the action chooses
                                        (:class:`~pickplace.envs.skill.PickPlaceEnv`)
``pickplace/Place-v0``                  one pick and place of a task: every object to its goal
``pickplace/Stack-v0``                  ... a tower of the objects
``pickplace/Clear-v0``                  ... everything into the bin (:class:`~pickplace.envs.skill.TaskEnv`)
``pickplace/PickPlaceLowLevel-v0``      1/20 s of control: a tcp (or joint) increment and a gripper command
                                        (:class:`~pickplace.envs.lowlevel.PickPlaceLowLevelEnv`)
======================================  ===========================================================================

Usage::

    import gymnasium as gym
    import pickplace.envs  # registers the ids

    env = gym.make("pickplace/PickPlace-v0", render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(0)  # the best-ranked grasp

``gym.make("pickplace.envs:pickplace/PickPlace-v0")`` imports the package itself. Gymnasium 1.x loads no
``gymnasium.envs`` entry points of installed packages (0.26 did), so the package declares none: importing it is
what registers the ids. Constructor arguments go through ``gym.make(id, **kwargs)``; invalid ones raise
:class:`~pickplace.errors.ConfigError` naming the argument, its value and what is allowed.
"""

from __future__ import annotations

try:
    import gymnasium as gym
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError("pickplace.envs needs Gymnasium: pip install 'pickplace[gym]'") from exc

from pickplace.envs.lowlevel import PickPlaceLowLevelEnv
from pickplace.envs.skill import ClearEnv, PickPlaceEnv, PlaceEnv, StackEnv, TaskEnv

#: The registered ids and their entry points.
ENV_IDS = {
    "pickplace/PickPlace-v0": "pickplace.envs.skill:PickPlaceEnv",
    "pickplace/Place-v0": "pickplace.envs.skill:PlaceEnv",
    "pickplace/Stack-v0": "pickplace.envs.skill:StackEnv",
    "pickplace/Clear-v0": "pickplace.envs.skill:ClearEnv",
    "pickplace/PickPlaceLowLevel-v0": "pickplace.envs.lowlevel:PickPlaceLowLevelEnv",
}


def _register() -> None:
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point)


_register()

__all__ = ["ENV_IDS", "ClearEnv", "PickPlaceEnv", "PickPlaceLowLevelEnv", "PlaceEnv", "StackEnv", "TaskEnv"]
