"""Gymnasium environment benchmark: env steps per second and real-time factor at both action levels, next to
robosuite's Lift measured in the same run, and the skill level's success over seeded episodes.

Run ``python benchmarks/env.py [--json] [--episodes N] [--steps N] [--rate HZ ...] [--rounds R] [--profile P]
[--robosuite [PYTHON]] [--robosuite-rates HZ ...]``; ``make bench-env`` first makes robosuite's own venv
(``.bench-venv/robosuite``, from ``benchmarks/robosuite-constraints.txt``) and passes it. The implementation lives
in :mod:`pickplace.eval.bench.env`.
"""

import sys

from pickplace.eval.bench.env import main

if __name__ == "__main__":
    sys.exit(main())
