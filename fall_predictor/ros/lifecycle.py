"""The monitor's nodes as managed (lifecycle) nodes.

An integrator's bring-up can hold the monitor until the robot is ready: each monitor node is a
``rclpy`` lifecycle node whose **configure** loads what it needs (the model and its feature
settings; the estimator then builds its robot model from ``robot_description``) and whose
**activate** starts it (inputs processed, states and the trigger published; deactivate stops it,
and the predictor then publishes the trigger ``false``). With ``autostart`` (the default) a node
configures and activates itself at start-up, and a configuration that fails stops the process
with one FATAL line, as a plain node would; without it, it waits in ``unconfigured`` for
``ros2 lifecycle set <node> configure`` / ``activate`` (or a lifecycle manager), and a failed
configure is logged and leaves it there.

Publishers and subscriptions exist from construction (the in-process hand-off of ``fall_monitor``
connects them then); an inactive node ignores its inputs and publishes nothing.
"""
from __future__ import annotations

from typing import Optional

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from fall_predictor.ros.parameters import NodeStartupError, ParamSpec

AUTOSTART = ParamSpec('autostart', True, 'configure and activate at start-up; false: wait in '
                      'unconfigured for the lifecycle manager (ros2 lifecycle set)', read_only=True)


class MonitorLifecycleNode(LifecycleNode):
    """A monitor node with the lifecycle above; subclasses implement :meth:`_configure` and may
    extend :meth:`_activate`, :meth:`_deactivate`, :meth:`_cleanup`."""

    def __init__(self, node_name: str, **kwargs: object) -> None:
        super().__init__(node_name, **kwargs)
        #: Inputs are processed and outputs published only while active.
        self.active = False
        #: Why the last configure failed (None: it did not).
        self.startup_error: Optional[NodeStartupError] = None
        # Configuring at start-up: a failure stops the process with one FATAL line (the runner's).
        self._autostarting = False

    # -- what a subclass does ----------------------------------------------------------------
    def _configure(self) -> None:
        """Load what the node needs; raise :class:`NodeStartupError` with the reason if it cannot."""
        raise NotImplementedError

    def _activate(self) -> None:
        """Start (after ``active`` is set)."""

    def _deactivate(self) -> None:
        """Stop (after ``active`` is cleared)."""

    def _cleanup(self) -> None:
        """Forget what :meth:`_configure` loaded."""

    # -- the lifecycle ---------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self._configure()
        except NodeStartupError as error:
            self.startup_error = error
            if not self._autostarting:      # at start-up the process's FATAL line says it
                self.get_logger().error(f'cannot configure: {error}')
            return TransitionCallbackReturn.FAILURE
        self.startup_error = None
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = True
        self._activate()
        self.get_logger().info('active')
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self._deactivate()
        self.get_logger().info('inactive')
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._cleanup()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        return TransitionCallbackReturn.SUCCESS

    def start(self, autostart: bool) -> None:
        """At the end of construction: configure and activate when ``autostart``; a failed
        configure then raises :class:`NodeStartupError` (the process stops with the reason)."""
        if not autostart:
            self.get_logger().info('waiting for the lifecycle manager (autostart false)')
            return
        self._autostarting = True
        try:
            configured = self.trigger_configure() == TransitionCallbackReturn.SUCCESS
        finally:
            self._autostarting = False
        if not configured:
            raise NodeStartupError(str(self.startup_error)) from self.startup_error
        self.trigger_activate()
