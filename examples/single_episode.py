"""Run one pick and place from Python and print what was measured.

    python examples/single_episode.py
"""

from __future__ import annotations

from pickplace.task.episode import EpisodeConfig, run_episode


def main() -> int:
    # A 300 g cube, turned by 30 degrees, carried over the wall to a goal 3 cm further out.
    config = EpisodeConfig().with_object(mass_kg=0.3).with_scene(start_yaw_rad=0.52, goal_xy_m=(0.38, -0.20),
                                                                  obstacle=True)
    result = run_episode(config, seed=1)
    if not result.success:
        print(f"failed in {result.failure_phase}: {result.failure_reason}")
        return 1
    print(f"placed {result.place_error_xy_m * 1e3:.2f} mm from the goal in {result.cycle_time_s:.2f} s "
          f"(simulated), tracking error {result.tracking_error_max_rad * 1e3:.3f} mrad")
    for phase, start, duration, _ in result.phase_timeline:
        print(f"  {phase:15s} {start:6.3f} s  +{duration:.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
