"""Publishing recorded messages at their due times from a benchmark that also receives (one
process, two threads).

A replay that sleeps until shortly before each due time and then spins on the clock keeps the
interpreter's lock while it spins; a receiving thread then runs only when the spinner sleeps or
the interpreter's switch interval (5 ms) runs out, and every message it receives meanwhile is
time-stamped late. At four to five sensor messages per millisecond the spin took most of each
period, and the robot's split joint states (the IMU 0.3 ms and the wrenches 0.4 ms after them)
read a p90 latency of 1.3 ms that was this process's, not the monitor's (0.43 ms once the spin
yields).
"""
from __future__ import annotations

import time

#: Sleep until this long before a due time, then yield until it (sleep overshoots by ~0.1 ms).
SPIN_S = 0.0003


def wait_until(due: float) -> None:
    """Return at ``time.monotonic()`` >= ``due``, releasing the CPU and the GIL meanwhile."""
    ahead = due - time.monotonic() - SPIN_S
    if ahead > 0.0:
        time.sleep(ahead)
    while time.monotonic() < due:
        time.sleep(0)               # releases the GIL: the receiving thread takes it if waiting
