"""Task benchmark: stack, place (with a swap) and clear over randomized trials, planned order against listed.

Run ``python benchmarks/tasks.py [--json] [--trials N] [--kinds stack,place,clear] [--workers W]``. The
implementation lives in :mod:`pickplace.eval.bench.tasks`.
"""

import sys

from pickplace.eval.bench.tasks import main

if __name__ == "__main__":
    sys.exit(main())
