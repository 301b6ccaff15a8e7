"""pma-exo from Python: the CLI's runs as numpy arrays, and a bench a Python controller steps.

See docs/python.md in the repository.
"""
from .pma_exo import *  # noqa: F401,F403
from .pma_exo import __doc__, __version__  # noqa: F401

__all__ = [
    "single",
    "simulate",
    "pendulum",
    "size",
    "identify",
    "fit_gait",
    "sweep",
    "Bench",
    "Leg",
    "PmaError",
    "SupervisorError",
    "CONTROLLERS",
    "PLANTS",
]
