"""The ranges of the disturbances beyond pushes a robot's datasets draw, per controller (the
profile's ``causes:``: top level for C_bal, ``controllers.<name>.causes`` for a learned policy),
as ``fall-predictor calibrate --cause`` measures them (sim/disturbance_runs.py: what each
parameter is, and the defaults of those a profile leaves out)::

    causes:
      trip: {height_m: [0.02, 0.06]}     # the obstacle's height [m]
      slip: {friction: [0.05, 0.2]}      # the patch's Coulomb friction
      step: {height_m: [0.05, 0.12]}     # a step's height (down or up) [m]
      fault: {torque_scale: [0.0, 0.3]}  # the share of a faulty drive's torque left
"""
from __future__ import annotations

import math
from typing import Any

#: The parameters each cause's ranges may set.
CAUSE_PARAMETERS: dict[str, tuple[str, ...]] = {
    'trip': ('height_m', 'depth_m'),
    'slip': ('friction',),
    'step': ('height_m', 'slope_deg'),
    'fault': ('torque_scale', 'fade_s', 'period_s', 'duty'),
    'walk': ('segment_s',),
}


def parse_cause_ranges(where: str, raw: Any) -> dict[str, dict[str, tuple[float, float]]]:
    """``causes:`` of a profile (ValueError naming ``where`` and the key when wrong)."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ValueError(f'{where}.causes must be a mapping of cause -> {{parameter: [low, high]}}')
    out = {}
    for cause, params in raw.items():
        if cause not in CAUSE_PARAMETERS:
            raise ValueError(f'{where}.causes: unknown cause {cause!r} (one of {", ".join(CAUSE_PARAMETERS)})')
        if not isinstance(params, dict):
            raise ValueError(f'{where}.causes.{cause} must be a mapping of parameter -> [low, high]')
        ranges = {}
        for name, pair in params.items():
            key = f'{where}.causes.{cause}.{name}'
            if name not in CAUSE_PARAMETERS[cause]:
                raise ValueError(f'{key}: unknown parameter (one of {", ".join(CAUSE_PARAMETERS[cause])})')
            if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                    or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                               for v in pair) or pair[0] > pair[1] or pair[0] < 0):
                raise ValueError(f'{key} must be [low, high], 0 <= low <= high')
            ranges[str(name)] = (float(pair[0]), float(pair[1]))
        out[str(cause)] = ranges
    return out
