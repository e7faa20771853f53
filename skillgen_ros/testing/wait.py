"""wait_for: poll an observable condition with a budget (never a bare sleep as synchronisation)."""
from __future__ import annotations

import time


def wait_for(predicate, timeout: float = 10.0, period: float = 0.02) -> bool:
    """Poll `predicate` until it is true or `timeout` s pass; its last truthiness."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return bool(predicate())
