"""pickplace: closed-loop pick and place with a simulated UR5e in MuJoCo.

The package is layered; an import only goes down: ``cli`` → ``eval`` (campaigns, reports, benchmarks) →
``task`` (state machine, episode) → ``grasping`` → ``motion`` (collision, planning, timing, control) →
``robot`` (model, kinematics, IK, gripper) → ``world`` (scene config, contacts) → ``errors``.

The most used names are available here, imported on first use (so that ``pickplace --help`` stays fast):
``EpisodeConfig``, ``EpisodeResult``, ``run_episode``, ``CampaignConfig``, ``run_campaign``.
"""

import importlib
import logging
from typing import Any

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

_LAZY = {
    "EpisodeConfig": "pickplace.task.episode",
    "EpisodeResult": "pickplace.task.episode",
    "run_episode": "pickplace.task.episode",
    "CampaignConfig": "pickplace.eval.campaign",
    "run_campaign": "pickplace.eval.campaign",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'pickplace' has no attribute {name!r}")


__all__ = ["CampaignConfig", "EpisodeConfig", "EpisodeResult", "__version__", "run_campaign", "run_episode"]
