"""Benchmarks shipped with the package so that ``pickplace bench NAME`` runs them from any install.

``benchmarks/NAME.py`` at the repository root are thin wrappers around these modules.
"""


def machine_info() -> dict[str, object]:
    """Where a benchmark ran: platform, cores, load, Python and MuJoCo versions (benchmarks report ratios
    measured side by side in one run because these machines are shared and noisy)."""
    import os
    import platform

    import mujoco

    return {"platform": platform.platform(), "cpu_count": os.cpu_count(), "load_average_1min": os.getloadavg()[0],
            "python": platform.python_version(), "mujoco": mujoco.__version__}
