"""Sample order in a 1 kHz stream: duplicates, out-of-order samples, gaps and runs.

ROS-free: the nodes (:mod:`fall_predictor.ros`) use it on their inputs, and it can be run
over recorded sample times offline.
"""
from __future__ import annotations

import math
from enum import Enum
from typing import Optional


class Sample(Enum):
    """How a sample time relates to the stream so far."""

    NEXT = 'next'                   #: later than the previous sample (or the first sample)
    NEW_RUN = 'new_run'             #: the restart rule was met: a new run starts here
    REPEAT = 'repeat'               #: the same time again: a duplicate, dropped
    OUT_OF_ORDER = 'out_of_order'   #: older than the previous sample: dropped
    RESTART_PENDING = 'restart_pending'  #: older, but may start a new run: dropped for now


class SampleIntake:
    """Orders one stream of sample times (nominal period ``period_s``) into runs.

    * A sample later than the previous one is accepted (NEXT); the samples missing on the
      ``period_s`` grid in between are counted in :attr:`missing` (gaps: DDS loss, a late
      publisher).
    * The same time again is a duplicate (REPEAT); an older time is dropped and counted as out
      of order (OUT_OF_ORDER).
    * **Restart rule.** A new run starts (NEW_RUN) without an explicit :meth:`reset` only when
      ``restart_samples`` consecutive samples are all older than the current run's last
      sample, strictly increasing, and the first of them lies within ``restart_window_s`` of
      t = 0 (every simulator reset restarts time at 0). One stray old stamp cannot meet it;
      the price is that the first ``restart_samples - 1`` samples of a restarted run are
      dropped (RESTART_PENDING). A later sample of the current run cancels a pending restart.
    """

    def __init__(self, period_s: float, restart_samples: int = 5,
                 restart_window_s: float = 1.0) -> None:
        if not (period_s > 0.0 and restart_samples >= 1 and restart_window_s >= 0.0):
            raise ValueError('need period_s > 0, restart_samples >= 1, restart_window_s >= 0')
        self.period_s = period_s
        self.restart_samples = restart_samples
        self.restart_window_s = restart_window_s
        self.runs = 0               #: runs started by the restart rule
        self.missing = 0            #: samples missing on the period grid (gaps)
        self.out_of_order = 0
        self.duplicates = 0
        self.reset()

    def reset(self) -> None:
        """Explicit new run: the next sample is accepted whatever its time."""
        self.last_t: Optional[float] = None
        self._pending: list[float] = []

    def classify(self, t: float) -> Sample:
        """Classify sample time ``t`` [s] (finite, within the plausibility bounds)."""
        last = self.last_t
        if last is None or t > last:
            if last is not None:
                # round() of a bounded float: t and last are within [0, 1e7] s.
                self.missing += max(0, round((t - last) / self.period_s) - 1)
            self._pending.clear()
            self.last_t = t
            return Sample.NEXT
        if t == last:
            self.duplicates += 1
            return Sample.REPEAT
        pending = self._pending
        if (pending and t > pending[-1]) or (not pending and t <= self.restart_window_s):
            pending.append(t)
            if len(pending) >= self.restart_samples:
                pending.clear()
                self.runs += 1
                self.last_t = t
                return Sample.NEW_RUN
            return Sample.RESTART_PENDING
        pending.clear()
        self.out_of_order += 1
        return Sample.OUT_OF_ORDER

    def counters(self) -> dict[str, int]:
        """Counts for ``/diagnostics``."""
        return {'missing_samples': self.missing, 'out_of_order': self.out_of_order,
                'duplicates': self.duplicates, 'restarts': self.runs}


class RunTracker:
    """Splits one stream of sample times into runs (the recorder's bag splitting; the
    monitor and controller nodes use :class:`SampleIntake`).

    Time going backwards starts a new run. With ``restart_at_zero`` a sample at exactly
    t = 0 also starts one even after another t = 0 sample: every fresh simulator world
    starts at t = 0, so a reset before the first step is still noticed. With
    ``max_start_t_s`` a jump back only starts a run if it lands before that time (runs start
    at t = 0); a smaller jump back is taken as an out-of-order sample of the same run.
    """

    def __init__(self, restart_at_zero: bool = True, max_start_t_s: float = math.inf) -> None:
        self.restart_at_zero = restart_at_zero
        self.max_start_t_s = max_start_t_s
        self.last_t: Optional[float] = None
        self.runs = 0               #: number of runs started after the first

    def classify(self, t: float) -> Sample:
        """Classify sample time ``t`` [s] and remember it (a REPEAT leaves the state as is)."""
        last = self.last_t
        if last is None or (t > last or (t < last and t >= self.max_start_t_s)):
            kind = Sample.NEXT
        elif t == last and not (self.restart_at_zero and t == 0.0):
            return Sample.REPEAT
        else:
            kind = Sample.NEW_RUN
            self.runs += 1
        self.last_t = t
        return kind
