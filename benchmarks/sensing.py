"""Sensing benchmark: success rate and place error of realistic episodes against the depth camera's noise and its
calibration error (paired trials, the campaigns' default randomization).

Run ``python benchmarks/sensing.py [--json] [--trials N] [--workers W] [--plot PATH.png] [--quick]`` or
``pickplace bench sensing ...``. The default run takes about 5-15 minutes on 2 cores. The implementation lives in
:mod:`pickplace.eval.bench.sensing`.
"""

import sys

from pickplace.eval.bench.sensing import main

if __name__ == "__main__":
    sys.exit(main())
