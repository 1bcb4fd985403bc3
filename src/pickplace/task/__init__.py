"""The task: the pick-and-place state machine, its per-step monitor, injected faults, telemetry, and the
episode that runs it all and returns the measured result."""
