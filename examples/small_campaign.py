"""A small randomized campaign from Python: 6 trials on 2 local worker processes.

    python examples/small_campaign.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, run_campaign


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0]) if args else Path(tempfile.mkdtemp(prefix="pickplace-campaign-"))
    spec = RandomizationSpec(object_mass_scale=(0.67, 2.67))  # the default ranges, heavier cubes (0.1-0.4 kg)
    run = run_campaign(CampaignConfig(randomization=spec, trials=6, seed=7, workers=2), out)
    s = run.summary
    print(f"{s.successes}/{s.trials} succeeded; place error RMS {s.place_error_xy_rms_m * 1e3:.2f} mm; "
          f"results in {out / 'results.jsonl'}")
    return 0 if s.successes == s.trials else 1


if __name__ == "__main__":
    raise SystemExit(main())
