"""Gymnasium environment benchmark: env steps per second and real-time factor at both action levels, and the
skill level's success over seeded episodes.

Run ``python benchmarks/env.py [--json] [--episodes N] [--steps N] [--rate HZ] [--profile P]``. The
implementation lives in :mod:`pickplace.eval.bench.env`.
"""

import sys

from pickplace.eval.bench.env import main

if __name__ == "__main__":
    sys.exit(main())
