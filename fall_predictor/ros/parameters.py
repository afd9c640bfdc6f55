"""Node parameters: declared with descriptors (range, description, read-only) and validated with a
reason (as ros2/demos do), and the model file with its feature settings that several nodes load.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Union

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter

from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.features import FeatureSettings, FeatureSettingsMismatch
from fall_predictor.monitor.model_file import (DEFAULT_MAX_MODEL_BYTES, ModelFileError,
                                              ModelMetadata, load_model)
from fall_predictor.profiles.profile import DEFAULT_ROBOT, ProfileError
from fall_predictor.ros.share import default_model_path

ParamValue = Union[bool, int, float, str]
#: A cross-parameter check: proposed values of all parameters -> reason to reject, or None.
CrossCheck = Callable[[Mapping[str, ParamValue]], Optional[str]]

class NodeStartupError(RuntimeError):
    """A node cannot start (missing model, bad configuration); the message says why."""


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ParamSpec:
    """One node parameter: default (its type is the parameter's type), description with the
    unit, optional inclusive range [low, high] for numbers, and whether it is read-only
    (settable only at start-up, from a params file or ``-p``)."""

    name: str
    default: ParamValue
    description: str
    low: Optional[float] = None
    high: Optional[float] = None
    read_only: bool = False
    #: A value below ``low`` that means "not set" (e.g. adopt the model's value), or None.
    unset: Optional[float] = None

    def descriptor(self) -> ParameterDescriptor:
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.low is not None and self.high is not None:
            low = self.low if self.unset is None else min(self.low, self.unset)
            if isinstance(self.default, float):
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=float(low), to_value=float(self.high))]
            elif isinstance(self.default, int) and not isinstance(self.default, bool):
                descriptor.integer_range = [
                    IntegerRange(from_value=int(self.low), to_value=int(self.high), step=1)]
        return descriptor

    def check(self, value: object) -> Optional[str]:
        """Why ``value`` is not acceptable for this parameter, or None if it is."""
        kind = type(self.default)
        if type(value) is not kind:
            return f'{self.name} must be a {kind.__name__}, got {value!r}'
        if isinstance(value, float) and not math.isfinite(value):
            return f'{self.name} must be finite, got {value!r}'
        if self.unset is not None and value == self.unset:
            return None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if (self.low is not None and value < self.low) or (
                    self.high is not None and value > self.high):
                unset = '' if self.unset is None else f' (or {self.unset} for unset)'
                return f'{self.name} = {value!r} is outside its range [{self.low}, {self.high}]{unset}'
        return None

    def value_or_none(self, value: ParamValue) -> Optional[ParamValue]:
        """``value``, or None if it is this parameter's ``unset`` value."""
        return None if self.unset is not None and value == self.unset else value


MODEL_PATH = ParamSpec(
    'model_path', '', 'model file (JSON); empty = the shipped model the robot profile names '
    '(models/ of the installed package, else of the source tree)', read_only=True)

MAX_MODEL_BYTES = ParamSpec(
    'max_model_bytes', DEFAULT_MAX_MODEL_BYTES, 'largest model file read [bytes]; only regular '
    'files are read (a FIFO or a device is refused)', 1, 2_000_000_000, read_only=True)

#: "Adopt the model's value": the unset value of the feature-settings parameters.
FROM_MODEL = -1.0


def feature_setting_params(names: Sequence[str]) -> tuple[ParamSpec, ...]:
    """Parameters for the model's feature settings (see
    :class:`~fall_predictor.monitor.features.FeatureSettings`), unset by default: a node adopts
    the model's value, and refuses to start if a set value differs from it."""
    specs = {
        'rate_window_s': ParamSpec('rate_window_s', FROM_MODEL, 'backward-difference window of '
                                   'the momentum rates [s]; -1 = the model\'s', 1e-4, 0.1,
                                   read_only=True, unset=FROM_MODEL),
        'edge_tolerance_m': ParamSpec('edge_tolerance_m', FROM_MODEL, 'distance [m] within which '
                                      'the CoP counts as on a support polygon edge; -1 = the '
                                      'model\'s', 0.0, 0.05, read_only=True, unset=FROM_MODEL),
        'sample_period_s': ParamSpec('sample_period_s', FROM_MODEL, 'nominal period of the '
                                     'measurements [s]; -1 = the model\'s', 1e-4, 0.1,
                                     read_only=True, unset=FROM_MODEL),
        'guard_com_height_m': ParamSpec('guard_com_height_m', FROM_MODEL, 'CoM guard: falling '
                                        'whenever the CoM is below this height [m]; -1 = the '
                                        'model\'s', 0.0, 2.0, read_only=True, unset=FROM_MODEL),
    }
    return tuple(specs[name] for name in names)


def load_model_for(node: Node, model_path: str, requested: Mapping[str, ParamValue],
                   max_bytes: int = DEFAULT_MAX_MODEL_BYTES, robot: str = DEFAULT_ROBOT
                   ) -> tuple[PerModeDecisionLists, ModelMetadata, FeatureSettings]:
    """Load the model named by ``model_path`` ('' = the shipped model ``robot``'s profile names)
    and resolve the node's feature-setting parameters against it: ``(lists, metadata, settings)``.

    Raises :class:`NodeStartupError` with one clear reason if the model cannot be used or a
    set parameter differs from the model's setting.
    """
    if model_path:
        path = Path(model_path).expanduser()
    else:
        try:
            path = default_model_path(robot)
        except ProfileError as error:
            raise NodeStartupError(f'robot profile: {error}') from error
        if not path.is_file():
            raise NodeStartupError(f'robot {robot!r} names the model {path.name}, which is not '
                                   f'shipped ({path} does not exist): train one for this robot '
                                   'and its controller and give it as model_path')
    try:
        lists, metadata = load_model(path, max_bytes)
    except ModelFileError as error:
        raise NodeStartupError(f'no usable model: {error}') from error
    specs = {spec.name: spec for spec in feature_setting_params(list(requested))}
    try:
        settings = metadata.feature_settings.resolve(
            {name: specs[name].value_or_none(value) for name, value in requested.items()},
            what=f'model {path}')
    except FeatureSettingsMismatch as error:
        raise NodeStartupError(f'feature settings differ from the model\'s: {error}') from error
    node.get_logger().info(f'model {path}: feature settings {settings}')
    return lists, metadata, settings


def declare_parameters(node: Node, specs: Sequence[ParamSpec],
                       cross_check: Optional[CrossCheck] = None) -> dict[str, ParamValue]:
    """Declare ``specs`` on ``node`` behind a validating on-set-parameters callback.

    The callback is registered first, so values from a params file or ``-p`` are validated at
    declaration too; any rejection at start-up raises :class:`NodeStartupError` with the
    reason. ``cross_check`` sees the proposed values of every parameter (current values with
    the change applied) once all are declared. Returns the declared values by name.
    """
    by_name = {spec.name: spec for spec in specs}

    def validate(parameters: list[Parameter]) -> SetParametersResult:
        proposed: dict[str, ParamValue] = {}
        for parameter in parameters:
            spec = by_name.get(parameter.name)
            if spec is None:
                continue            # not ours (e.g. use_sim_time): leave it to its owner
            reason = spec.check(parameter.value)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
            proposed[parameter.name] = parameter.value
        if cross_check is not None and all(node.has_parameter(name) for name in by_name):
            merged = {name: node.get_parameter(name).value for name in by_name}
            merged.update(proposed)
            reason = cross_check(merged)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)
    try:
        for spec in specs:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())
    except ParameterException as error:
        raise NodeStartupError(f'invalid parameter: {error}') from error
    values = {spec.name: node.get_parameter(spec.name).value for spec in specs}
    if cross_check is not None:
        reason = cross_check(values)
        if reason is not None:
            raise NodeStartupError(f'invalid parameters: {reason}')
    return values
