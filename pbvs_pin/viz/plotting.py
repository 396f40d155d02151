"""What every matplotlib figure of a run shares: the Agg pyplot and the run's title.

matplotlib is imported on first use, so that the control core never loads it; the Agg backend
writes figures without a display.
"""

from __future__ import annotations

from pbvs_pin.sim.log import RunLog


def pyplot():
    """matplotlib.pyplot on the Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def run_title(log: RunLog) -> str:
    """``"<robot>, <experiment>, <law> law"`` from a log's meta."""
    return f"{log.meta['robot']}, {log.meta['scenario']}, {log.meta['law']} law"
