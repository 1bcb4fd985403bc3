"""Campaign benchmark: trials per second with 1 and 2 workers in one run (scaling), and a 50-trial campaign.

Run ``python benchmarks/campaign.py [--json] [--trials K] [--repeats R] [--campaign N]``. The implementation
lives in :mod:`pickplace.eval.bench.campaign`.
"""

import sys

from pickplace.eval.bench.campaign import main

if __name__ == "__main__":
    sys.exit(main())
