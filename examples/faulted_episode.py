"""Knock the cube out of the grip on purpose and watch the machine detect it and pick it up again.

    python examples/faulted_episode.py
"""

from __future__ import annotations

import dataclasses

from pickplace.task.episode import EpisodeConfig, run_episode
from pickplace.task.faults import FaultConfig
from pickplace.task.machine import MachineConfig


def main() -> int:
    push = FaultConfig(transport_push_n=(0.0, 0.0, -40.0), transport_push_start_s=0.2, transport_push_s=0.05)
    for retries in (0, 3):  # recovery off, then on
        config = dataclasses.replace(EpisodeConfig(), faults=push, machine=MachineConfig(max_retries=retries))
        result = run_episode(config, seed=0)
        outcome = "success" if result.success else f"FAILED in {result.failure_phase}: {result.failure_reason}"
        print(f"max_retries={retries}: {outcome}")
        for line in result.recoveries:
            print(f"  recovery: {line}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
