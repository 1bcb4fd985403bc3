"""Closed-loop benchmark: whole episodes (default, obstacle, realistic, three-object stack) against a bare mj_step
replay of their own torques, and their real-time factors, in one run.

Run ``python benchmarks/loop.py [--json] [--repeats R] [--cases ...]``. The implementation lives in
:mod:`pickplace.eval.bench.loop`.
"""

import sys

from pickplace.eval.bench.loop import main

if __name__ == "__main__":
    sys.exit(main())
