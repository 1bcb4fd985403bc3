"""Planning benchmark: pickplace's planner against OMPL's RRTConnect and RRT*, side by side in one run, on the
pick-and-place segments of the default and obstacle scenes and on harder problems (shelf, cage, bins, slot).

OMPL's planners run twice: over the full joint bounds (``ompl-rrtconnect``, ``ompl-rrtstar``) and with their
state space bounds set to the box pickplace samples in, ±1 rad around start and goal (``ompl-rrtconnect-box``,
``ompl-rrtstar-box``); every row of the table and of the ``--json`` output says where it sampled.

Run ``make bench`` (installs the ``bench`` extra with OMPL) or ``pickplace bench planning [--json]``.
The implementation lives in :mod:`pickplace.eval.bench.planning`.
"""

import sys

from pickplace.eval.bench.planning import main

if __name__ == "__main__":
    sys.exit(main())
