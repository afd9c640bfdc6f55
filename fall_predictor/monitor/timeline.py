"""Sample stamps as a robot publishes them: ROS time in, run time out (method §12).

A robot stamps its sensor messages with ROS time: integer nanoseconds since 1970 on a real robot,
simulation time under ``use_sim_time``; each sensor on its own clock and rate. Inside, the monitor
works on **run time**: float seconds since the anchor of the current run (small numbers, full float
precision; the sample-time bounds of :mod:`~fall_predictor.monitor.plausibility` apply to it). Every
stamp the monitor publishes is its input's own integer stamp, never a value converted back from run
time.

:class:`StampTimeline` is the one rule every node applies to its input stream (live and offline):

* **next**: a stamp after the previous accepted one by at most ``max_step_s`` is accepted; samples
  missing on the stream's period (estimated from the stream itself) are counted;
* **step forward**: a stamp further than ``max_step_s`` after the previous accepted one is held
  (dropped, counted as missing); if the next one follows it (by at most ``max_step_s``), the
  sensor paused or its clock stepped forward, and a new run starts there (:data:`Stamp.NEW_RUN`):
  whatever a consumer integrated or windowed across the step (an estimator's dead reckoning, a
  momentum-rate window, the history window) is no longer about the same motion. The samples of
  the step are counted missing on the stream's period (a pause and a clock step cannot be told
  apart). If the next one belongs to the run instead, the held stamp was a stray (far future,
  ``sec = 2^31 - 1``);
* **duplicate**: the same stamp again is dropped;
* **out of order**: a stamp before the previous accepted one, by at most ``max_step_s``, is dropped;
* **jump back**: any stamp before the previous accepted one (an old sample, a stray from the far
  past, or the first sample after the clock was set back or a simulator restarted) is held as a
  candidate and dropped. ``jump_samples`` consecutive candidates that are consistent with each
  other (each after the one before by at most ``max_step_s``) are a real clock jump: the timeline
  re-anchors there and a new run starts (:data:`Stamp.NEW_RUN`), without a reset call. A sample of
  the current run in between discards the candidates (counted as strays, or as out of order when
  they were less than ``max_step_s`` old): one stray stamp neither blinds the monitor nor starts a
  new run.

The first sample after construction or :meth:`StampTimeline.reset` anchors a run whatever its stamp;
if it was a stray, the stream re-anchors after ``jump_samples`` samples (two, when it lay in the past).

A consumer fed by a producer that already applies this rule (a node of the same process, which only
hands on accepted stamps and says which one starts a new run) calls :meth:`StampTimeline.restart`
at the producer's new run instead of confirming the step again from its own samples.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Optional

#: Nanoseconds per second.
NS_PER_S = 1_000_000_000


class Stamp(Enum):
    """How one stamp relates to the stream so far."""

    NEXT = 'next'                   #: accepted: later than the previous accepted stamp
    NEW_RUN = 'new_run'             #: accepted: a clock jump was confirmed; a new run starts here
    DUPLICATE = 'duplicate'         #: dropped: the previous accepted stamp again
    OUT_OF_ORDER = 'out_of_order'   #: dropped: slightly older than the previous accepted stamp
    JUMP_PENDING = 'jump_pending'   #: dropped: far from the run; a clock jump if more follow

    @property
    def accepted(self) -> bool:
        return self is Stamp.NEXT or self is Stamp.NEW_RUN


@dataclass(frozen=True)
class TimelineConfig:
    """The time rule's two numbers (see the module docstring)."""

    #: Largest step between consecutive samples of one run [s]; a longer step is a jump.
    max_step_s: float = 0.5
    #: Consecutive, mutually consistent samples that confirm a clock jump.
    jump_samples: int = 5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_step_s) and self.max_step_s > 0.0):
            raise ValueError(f'max_step_s must be a finite number > 0 [s], got {self.max_step_s!r}')
        if not (isinstance(self.jump_samples, int) and self.jump_samples >= 1):
            raise ValueError(f'jump_samples must be an integer >= 1, got {self.jump_samples!r}')


class StampTimeline:
    """Classifies a stream of integer stamps [ns] and gives each accepted one its run time [s]."""

    def __init__(self, config: TimelineConfig = TimelineConfig()) -> None:
        self.config = config
        self._max_step_ns = round(config.max_step_s * NS_PER_S)
        self.duplicates = 0         #: dropped: the same stamp again
        self.out_of_order = 0       #: dropped: slightly older than the previous
        self.strays = 0             #: dropped: jump candidates discarded by a sample of the run
        self.jumps = 0              #: clock steps back confirmed (new runs without a reset)
        self.pauses = 0             #: steps forward confirmed: a pause or a clock stepped ahead
        #: The latest new run's clock step [s] (negative: back): from where the old timeline would
        #: have put its next sample to the new timeline's first stamp.
        self.last_step_s = 0.0
        self.missing = 0            #: samples missing on the stream's estimated period
        self.reset()

    def reset(self) -> None:
        """Explicit new run: the next stamp anchors it, whatever its value."""
        self.anchor_ns: Optional[int] = None
        self.last_ns: Optional[int] = None
        self._ahead: Optional[int] = None  # a stamp far ahead of the run, held (see classify)
        self._candidates: list[int] = []
        self._period_ns: Optional[float] = None

    @property
    def period_s(self) -> Optional[float]:
        """The stream's sample period as estimated so far [s], or None."""
        return None if self._period_ns is None else self._period_ns / NS_PER_S

    def run_time(self, stamp_ns: int) -> float:
        """Run time [s] of an accepted stamp: seconds since the current run's anchor."""
        assert self.anchor_ns is not None, 'no run yet'
        return (stamp_ns - self.anchor_ns) / NS_PER_S

    def last_run_time(self) -> Optional[float]:
        """Run time [s] of the latest accepted stamp, or None before the first."""
        return None if self.last_ns is None else self.run_time(self.last_ns)

    def classify(self, stamp_ns: int) -> Stamp:
        """Classify ``stamp_ns`` (an integer, ROS time in nanoseconds) and remember it."""
        last = self.last_ns
        if last is None:
            self._anchor(stamp_ns)
            return Stamp.NEXT
        held = self._ahead
        self._ahead = None
        if held is not None and 0 < stamp_ns - held <= self._max_step_ns:
            # The stamp held ahead of the run is followed: the sensor paused or its clock stepped
            # forward (the held sample, dropped, is one of the missing); a new run starts here.
            self._discard_candidates()
            self._count_missing(stamp_ns - last)
            return self._new_run(stamp_ns, held)
        if held is not None:
            self.strays += 1
        step = stamp_ns - last
        if step > self._max_step_ns:
            self._ahead = stamp_ns          # a pause or a stray: the next stamp will tell
            return Stamp.JUMP_PENDING
        if 0 < step:
            if self._candidates:
                self._discard_candidates()
            self._count_missing(step)
            self.last_ns = stamp_ns
            return Stamp.NEXT
        if step == 0:
            self.duplicates += 1
            return Stamp.DUPLICATE
        return self._jump_candidate(stamp_ns, -self._max_step_ns <= step < 0)

    def _jump_candidate(self, stamp_ns: int, out_of_order: bool) -> Stamp:
        candidates = self._candidates
        if candidates and not 0 < stamp_ns - candidates[-1] <= self._max_step_ns:
            self._discard_candidates()          # not consistent with the ones before: start over
        candidates.append(stamp_ns)
        if len(candidates) < self.config.jump_samples:
            if out_of_order:
                self.out_of_order += 1
                return Stamp.OUT_OF_ORDER
            return Stamp.JUMP_PENDING
        return self._new_run(stamp_ns, candidates[0])

    def _new_run(self, stamp_ns: int, first_ns: Optional[int] = None) -> Stamp:
        """A new run anchored at ``stamp_ns``; ``first_ns``: the first stamp of the new timeline
        (the held one, or the first of the confirming candidates), from which the step is told:
        the clock's step is how far that stamp lies from where the old timeline would have put
        the next sample."""
        first_ns = stamp_ns if first_ns is None else first_ns
        if self.last_ns is not None and first_ns > self.last_ns:
            self.pauses += 1
        else:
            self.jumps += 1
        if self.last_ns is not None:
            period = self._period_ns or 0.0
            self.last_step_s = (first_ns - self.last_ns - period) / NS_PER_S
        self._anchor(stamp_ns)
        return Stamp.NEW_RUN

    def restart(self, stamp_ns: int) -> None:
        """A new run at ``stamp_ns`` that an upstream producer applying this rule has confirmed
        (counted as a clock jump; see the module docstring)."""
        self._new_run(stamp_ns)

    def _discard_candidates(self) -> None:
        last = self.last_ns
        self.strays += sum(1 for c in self._candidates if not -self._max_step_ns <= c - last < 0)
        self._candidates.clear()

    def _anchor(self, stamp_ns: int) -> None:
        self.anchor_ns = self.last_ns = stamp_ns
        self._candidates.clear()
        self._ahead = None
        self._period_ns = None
        self._regular_steps = 0

    def _count_missing(self, step_ns: int) -> None:
        """Count the samples missing in a step, on the stream's period, and learn the period
        from the regular steps: their running mean (a slow average after 100 of them); a step
        under half the period so far restarts the learning (the first step was a gap)."""
        period = self._period_ns
        if period is not None and step_ns > 1.5 * period:
            self.missing += round(step_ns / period) - 1
            return
        if period is None or step_ns < 0.5 * period:
            self._period_ns, self._regular_steps = float(step_ns), 1
            return
        self._regular_steps += 1
        self._period_ns = period + max(0.01, 1.0 / self._regular_steps) * (step_ns - period)

    def counters(self) -> dict[str, int]:
        """Counts for ``/diagnostics``."""
        return {'duplicates': self.duplicates, 'out_of_order': self.out_of_order,
                'stray_stamps': self.strays, 'clock_jumps': self.jumps, 'pauses': self.pauses,
                'missing_samples': self.missing}
