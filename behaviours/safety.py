"""The safety layer over a mission (paper section 2.2: the pilot in command and the ground station
can always take over; link loss returns the aircraft home). Thin leaves, one check or one action each:

- :class:`PilotGate`: the pilot's autonomy switch (an RC channel) is high. It also writes the
  mission time autonomy was last (re-)enabled to ``/safety/enabled_since``: the pilot's switch,
  off and on again, is what re-enables autonomy after any latched safety event.
- :class:`ModeOverridden`: since autonomy was enabled, a flight mode the mission did not command
  appeared in flight (a ground station, the pilot's mode switch, an ArduCopter failsafe).
- :class:`LinkLost`: no telemetry for ``max_silence_s`` on the mission clock.
- :class:`GeofenceBreached`: the vehicle is outside the mission's fence.
- :class:`Latch`: a decorator that holds its child's SUCCESS until autonomy is re-enabled, so an
  RTL for a breach is not undone when the aircraft comes back inside.
- :class:`YieldToPilot`: command nothing: release the RC override, and (optionally) hand a GUIDED
  aircraft to the pilot in LOITER, once; RUNNING until landed and disarmed.

The chase tree's ``Safety`` subtree (trees/subtrees/safety.xml, docs/chase.md) arranges them.
"""

from __future__ import annotations

import math
from typing import Any, Iterator, Mapping

import py_trees

from behaviours.base import FlightMode, VehicleBehaviour, optional_input, state_port
from chaser_bt.mission.geofence import Geofence
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour
from chaser_bt.vehicle import Command, VehicleState
from chaser_bt.vehicle.mode_authority import ModeAuthority
from chaser_bt.vehicle.touchdown import Touchdown, TouchdownJudge

Status = py_trees.common.Status

ENABLED_SINCE_KEY = "/safety/enabled_since"
#: ArduPilot's aux-switch thresholds (RC_Channel.h AUX_SWITCH_PWM_TRIGGER_HIGH/LOW): above 1800 is high.
SWITCH_HIGH_PWM = 1800


@register_behaviour
class PilotGate(VehicleBehaviour):
    """SUCCESS while the pilot's switch on RC ``channel`` is above ``on_above_pwm`` (autonomy allowed).

    An unknown channel (no RC_CHANNELS yet) is off. ``channel: 0`` means no switch: always allowed.
    Writes the mission time of the latest off -> on change to ``enabled_since``.
    """

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "channel": input_port(int, "RC channel of the pilot's autonomy switch (1-18; 0 = no switch)", default=7, minimum=0, maximum=18),
        "on_above_pwm": input_port(int, "The switch is on above this PWM (ArduPilot: high > 1800)", default=SWITCH_HIGH_PWM, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"enabled_since": output_port(float, "Mission time autonomy was last enabled",
                                                 default_key=ENABLED_SINCE_KEY)}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self._was_on = False

    def update(self) -> Status:
        channel, rc = self.get_input("channel"), self.state.rc_channels
        if channel == 0:
            on, self.feedback_message = True, "no pilot switch configured"
        elif 1 <= channel <= len(rc):
            pwm = rc[channel - 1]
            on = pwm > self.get_input("on_above_pwm")
            self.feedback_message = f"RC{channel} {pwm}: autonomy {'allowed' if on else 'off'}"
        else:
            on, self.feedback_message = False, f"RC{channel} not reported yet: autonomy off"
        if on and not self._was_on:
            self._set_output("enabled_since", self._now())
        self._was_on = on
        return Status.SUCCESS if on else Status.FAILURE


@register_behaviour
class ModeOverridden(VehicleBehaviour):
    """SUCCESS when, since ``enabled_since``, an armed vehicle changed to a mode the mission did not ask for.

    The mission's own requests are seen on the link as they are sent
    (:class:`chaser_bt.vehicle.mode_authority.ModeAuthority`); a ground station's, the pilot's mode
    switch and ArduCopter's failsafes are not. The feedback names the mode and the vehicle's reason.
    """

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "enabled_since": input_port(float, "Changes before this mission time are ignored", required=False,
                                    default_key=ENABLED_SINCE_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self.authority = ModeAuthority.attach(self._link(), self._now)

    def update(self) -> Status:
        since = optional_input(self, "enabled_since")
        change = self.authority.foreign_since(-math.inf if since is None else since, armed_only=True)
        if change is None:
            self.feedback_message = f"mode {self.state.mode or '?'} is the mission's"
            return Status.FAILURE
        self.feedback_message = f"{change.previous} -> {change.mode} at {change.t:.1f} s ({change.why or 'no reason given'})"
        return Status.SUCCESS


@register_behaviour
class LinkLost(VehicleBehaviour):
    """SUCCESS when no vehicle telemetry has arrived for ``max_silence_s`` of mission time, or the
    telemetry that arrives cannot be trusted (``VehicleState.telemetry_fault``: a flood of absurd
    values, a second sender under the vehicle's ids): a link that lies is a lost link.

    Keep it below the link's ``quiet_timeout_s`` (5 s), after which the runner stops the mission,
    and below ArduCopter's FS_GCS_TIMEOUT (5 s), so the mission asks for the RTL its autopilot is
    about to fly anyway rather than anything else. Before the first telemetry: not lost.
    """

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "max_silence_s": input_port(float, "Lost after this long without telemetry (s)", default=3.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self._last_t_boot = math.nan
        self._heard_at: float | None = None

    def update(self) -> Status:
        now, t_boot = self._now(), self.state.t_boot_s
        if self.state.telemetry_fault:
            self.feedback_message = self.state.telemetry_fault
            return Status.SUCCESS
        if not math.isnan(t_boot) and t_boot != self._last_t_boot:
            self._last_t_boot, self._heard_at = t_boot, now
        if self._heard_at is None:
            self.feedback_message = "no telemetry yet"
            return Status.FAILURE
        silence = now - self._heard_at
        self.feedback_message = f"telemetry {silence:.1f} s old"
        return Status.SUCCESS if silence > self.get_input("max_silence_s") else Status.FAILURE


@register_behaviour
class GeofenceBreached(VehicleBehaviour):
    """SUCCESS when the vehicle's position is outside the fence: a cylinder of ``radius_m`` around
    ``center_en`` and/or a ``polygon_en`` (east/north pairs), under a ``max_alt_m`` ceiling (0 = unused)."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "radius_m": input_port(float, "Cylinder radius around center_en (m); 0 = none", default=0.0, minimum=0),
        "center_en": input_port(list[float], "Cylinder centre [east, north] (m)", default=[0.0, 0.0], length=2),
        "polygon_en": input_port(list[float], "Polygon [e1, n1, e2, n2, ...] (m); empty = none", default=[]),
        "max_alt_m": input_port(float, "Ceiling above home (m); 0 = none", default=0.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> list[tuple[str, str]]:
        """A fence that cannot be built is a validation problem, never a surprise in flight."""
        neutral = {"radius_m": 0.0, "max_alt_m": 0.0, "polygon_en": [], "center_en": [0.0, 0.0]}
        try:  # ports wired to the blackboard are not known yet: check what is
            _fence(lambda port: neutral[port] if values.get(port) is None else values[port])
        except (ValueError, TypeError) as e:
            return [("polygon_en" if "polygon" in str(e) else "radius_m", str(e))]
        return []

    def update(self) -> Status:
        try:
            fence = _fence(self.get_input)
        except (ValueError, TypeError) as e:  # wired from the blackboard to something unusable
            self.feedback_message = f"no usable fence: {e}"
            return Status.FAILURE
        why = fence.breach(self.state.position_enu)
        self.feedback_message = why or "inside the fence"
        return Status.FAILURE if why is None else Status.SUCCESS


def _fence(get: Any) -> Geofence:
    return Geofence(get("radius_m"), get("max_alt_m"), tuple(get("polygon_en")), tuple(get("center_en")))


@register_behaviour
class Latch(py_trees.ports.PortsMixin, py_trees.decorators.Decorator):
    """Once the child succeeds, SUCCESS without ticking it again until ``reset`` changes value.

    ``reset`` defaults to ``/safety/enabled_since``: a latched safety event (a breach, a lost link)
    holds until the pilot's switch re-enables autonomy. Otherwise the child's status passes through.
    """

    INPUT_PORTS = {"reset": input_port(float, "Unlatch when this value changes", required=False,
                                       default_key=ENABLED_SINCE_KEY)}
    OUTPUT_PORTS: dict = {}

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.latched = False
        self._latched_on: Any = None

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        reset = optional_input(self, "reset")
        if self.latched and reset != self._latched_on:
            self.latched = False
        if self.latched:
            self.status = Status.SUCCESS
            self.feedback_message = f"latched: {self.decorated.feedback_message}"
            yield self
            return
        yield from self.decorated.tick()
        self.status = self.decorated.status
        self.feedback_message = self.decorated.feedback_message
        if self.status == Status.SUCCESS:
            self.latched, self._latched_on = True, reset
        yield self

    def update(self) -> Status:
        """Unused: :meth:`tick` decides the status."""
        return self.status


@register_behaviour
class YieldToPilot(VehicleBehaviour):
    """Command nothing: release the RC override and, with ``hand_back``, switch a GUIDED aircraft
    (where the sticks do nothing) to ``handback_mode`` once; then only watch.

    RUNNING; SUCCESS once the aircraft has touched down and disarmed after flying (the mission is
    over); FAILURE when it is disarmed in the air (a crash is not the end of a mission). A halted mission leaf may still send its hover after this leaf's first tick (the tree
    halts it afterwards): an RC override re-held that way is released on the next tick.
    """

    NODE_KIND = NodeKind.ACTION
    INPUT_PORTS = {
        "hand_back": input_port(bool, "Switch a GUIDED aircraft to handback_mode", default=True),
        "handback_mode": input_port(FlightMode, "Mode the pilot gets the aircraft in", default=FlightMode.LOITER),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._flew = self.state.airborne
        self._touchdown = TouchdownJudge()
        self._mode_cmd: Command | None = None
        self._release_held_sticks()
        if self.get_input("hand_back") and self.state.armed and self.state.mode == "GUIDED":
            self._mode_cmd = self._link().set_mode(self.get_input("handback_mode").name)

    def update(self) -> Status:
        state: VehicleState = self.state
        self._flew |= state.airborne
        verdict = self._touchdown.observe(self._now(), state)
        self._release_held_sticks()
        if self._flew and verdict is not Touchdown.FLYING:
            self.feedback_message = self._touchdown.detail
            return Status.SUCCESS if verdict is Touchdown.LANDED else Status.FAILURE
        handing = self._mode_cmd is not None and not self._mode_cmd.done
        self.feedback_message = f"pilot has the aircraft ({state.mode or '?'})" + (" : handing back" if handing else "")
        return Status.RUNNING

    def _release_held_sticks(self) -> None:
        link = self._link()
        if link.last_setpoint is not None and link.last_setpoint.kind == "rc_override":
            link.release_rc()
