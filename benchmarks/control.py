"""Control benchmark: tracking error and the cost of a control step against a bare mj_step, in one run.

Run ``python benchmarks/control.py [--json]``. The implementation lives in :mod:`pickplace.eval.bench.control`.
"""

import sys

from pickplace.eval.bench.control import main

if __name__ == "__main__":
    sys.exit(main())
