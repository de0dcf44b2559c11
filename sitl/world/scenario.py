"""Simulator scenarios: where the field is, the weather, the airframe, the autopilot's parameters,
how long it takes to boot and which faults strike when. The format is documented, key by key,
in ``sitl/scenarios/README.md``.

A scenario is loaded from YAML into frozen dataclasses. Every problem is reported as a
:class:`ScenarioError` naming the file, the key path and what was expected, so a typo in a
rehearsal's scenario fails before anything flies.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from chaser_bt.geo import GeoPoint
from chaser_bt.shipped import NotShipped, resolve_tree
from chaser_bt.vision.camera import MOUNTS, CameraModel
from sitl.vehicle.airframe import AirframeParams
from sitl.vehicle.params import ParamStore
from sitl.vehicle.physics import WindParams
from sitl.vehicle.setup import (
    FAULT_KINDS,
    GCS_MODES,
    BootParams,
    Fault,
    GroundStationEvent,
    PilotEvent,
    PilotScript,
)
from sitl.world.camera.lighting import LightingOverride
from sitl.world.camera.models import TARGET_MODELS
from sitl.world.camera.world import ANY_FAMILY, FAMILIES, WorldSpec
from sitl.world.intruders import (
    MANOEUVRE_KINDS,
    MAX_FLOCK,
    TRAJECTORY_KINDS,
    BirdSpec,
    IntruderLimits,
    IntruderSpec,
    Manoeuvre,
)
from sitl.world.radar.config import RadarClutter, RadarConfig, RadarFailureRates, RadarSignature
from sitl.world.targets import CirclePath, StaticPoint, TargetPath, WaypointPath

__all__ = ["ScheduledRetask", "ScenarioError", "BootParams", "Fault", "FAULT_KINDS", "GCS_MODES", "GroundStationEvent", "PilotEvent",
           "PilotScript", "RADAR_BLIND_KINDS", "Scenario", "ScriptedTarget", "BirdSpec", "load_scenario"]

INTRUDER_AIRFRAMES = ("phantom", "s1000")  # drone models the rendered camera draws (sitl/world/camera/models.py)

#: Target kinds the ground radar does not see: it tracks moving drones, not people on the ground.
RADAR_BLIND_KINDS = ("person",)

# 2026-01-01T00:00:00Z: a fixed boot epoch so SYSTEM_TIME, and with it every run, reproduces.
DEFAULT_START_UNIX_S = 1767225600.0


class ScenarioError(ValueError):
    """A scenario that cannot be used: the message names file, key path and expectation."""


@dataclass(frozen=True)
class ScriptedTarget:
    """A target flying a scripted path, present from ``start_s`` until ``end_s`` (None: to the end).

    ``kind`` is what the camera draws (a :data:`sitl.world.camera.models.TARGET_MODELS` key); the radar
    does not see :data:`RADAR_BLIND_KINDS`; ``radar`` is how it sees the others (None: the radar's defaults).
    """

    name: str
    path: TargetPath
    start_s: float = 0.0
    end_s: float | None = None
    kind: str = "s1000"
    radar: RadarSignature | None = None

    def present(self, t: float) -> bool:
        return t >= self.start_s and (self.end_s is None or t < self.end_s)

    @property
    def radar_visible(self) -> bool:
        """Whether the ground radar sees this target (drones yes, people no)."""
        return self.kind not in RADAR_BLIND_KINDS


@dataclass(frozen=True)
class OnboardCamera:
    """How the chaser carries its camera: ``mount`` (a :data:`chaser_bt.vision.camera.MOUNTS` name) and
    the optical axis's tilt, deg down, below the body's forward axis (fixed) or the horizon (stabilised)."""

    mount: str = CameraModel.mount
    tilt_deg: float = math.degrees(CameraModel.tilt_rad)


@dataclass(frozen=True)
class ScheduledRetask:
    """A retask a rehearsal gives the mission at simulated time ``at_s``: fly the tree file ``tree``
    instead, or with ``subtree`` put its tree in place of that subtree only (the simulator ignores it;
    ``sitl.bench.rehearsal`` offers it to the mission runner)."""

    at_s: float
    tree: Path
    subtree: str | None = None


@dataclass(frozen=True)
class Scenario:
    """Everything the simulator needs to start a run."""

    name: str
    home: GeoPoint
    home_heading_deg: float = 0.0
    wind: WindParams = field(default_factory=WindParams)
    airframe: AirframeParams = field(default_factory=AirframeParams)
    params: dict[str, float] = field(default_factory=dict)
    boot: BootParams = field(default_factory=BootParams)
    faults: tuple[Fault, ...] = ()
    time_limit_s: float = 600.0
    start_unix_s: float = DEFAULT_START_UNIX_S
    radar: RadarConfig | None = None
    targets: tuple[ScriptedTarget, ...] = ()
    intruders: tuple[IntruderSpec, ...] = ()
    pilot: PilotScript | None = None
    ground_station: tuple[GroundStationEvent, ...] = ()
    camera_world: WorldSpec = field(default_factory=WorldSpec)  # what the rendered camera looks at
    camera: OnboardCamera = field(default_factory=OnboardCamera)  # how the chaser carries it
    birds: tuple[BirdSpec, ...] = ()
    retasks: tuple[ScheduledRetask, ...] = ()

    @property
    def lighting(self) -> LightingOverride | None:
        """The scenario's ``lighting`` keys (carried to the camera world in ``camera_world.lighting``)."""
        return self.camera_world.lighting

    def fault_active(self, kind: str, t: float) -> bool:
        """Whether any fault of ``kind`` is in force at sim time ``t``."""
        return any(f.kind == kind and f.active(t) for f in self.faults)

    def placed(self, seed: int) -> Scenario:
        """This scenario with every scattered static target put at its point for ``seed``.

        Each target draws from its own stream (seed, index), so one run's placement does not depend
        on the other targets; a scenario without scatter is returned unchanged.
        """
        targets = tuple(
            dataclasses.replace(tgt, path=tgt.path.placed(np.random.default_rng([seed, 0x9e2, k])))
            if isinstance(tgt.path, StaticPoint) and tgt.path.scatter_m > 0 else tgt
            for k, tgt in enumerate(self.targets))
        return self if targets == self.targets else dataclasses.replace(self, targets=targets)

    @classmethod
    def from_dict(cls, d: Any, source: str = "<dict>") -> Scenario:
        """Validate a parsed YAML document; errors name ``source`` and the key path."""
        return _Parser(source).scenario(d)


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario YAML file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"{p}: cannot read scenario: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise ScenarioError(f"{p}: not a scenario: byte {e.start} is not UTF-8 text (a binary file?)") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ScenarioError(f"{p}: not valid YAML: {e}") from e
    except ValueError as e:  # an integer of thousands of digits: int() refuses it
        raise ScenarioError(f"{p}: not a scenario: {str(e).split(':')[0]}") from None
    except RecursionError:
        raise ScenarioError(f"{p}: not a scenario: YAML nested too deeply to read") from None
    return Scenario.from_dict(doc, source=str(p))


def _retask_tree(base: Path, tree: str) -> Path | None:
    """A retask's tree file: ``tree`` relative to the scenario's folder, else the shipped tree of that name
    (``sar``: found in a checkout and in an installed wheel alike); None when it is neither."""
    if (base / tree).is_file():
        return base / tree
    try:
        file = resolve_tree(tree)
    except NotShipped:
        return None
    return file if file.is_file() else None


def _finite(v: float) -> bool:
    """``math.isfinite``, false (not OverflowError) for an integer too large for a float."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


class _Parser:
    """Walks a scenario document, checking each key against what it should hold."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, expected: str, got: Any = dataclasses.MISSING) -> ScenarioError:
        where = f"{self.source}: {path}" if path else self.source
        tail = "" if got is dataclasses.MISSING else f", got {got!r}"
        return ScenarioError(f"{where}: expected {expected}{tail}")

    def mapping(self, d: Any, path: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
        if d is None:
            return {}
        if not isinstance(d, Mapping):
            raise self.fail(path, "a mapping", d)
        for key in d:
            if key not in allowed:
                at = f"{path}.{key}" if path else str(key)
                close = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"; did you mean {close[0]}?" if close else ""
                raise self.fail(at, "one of the keys " + ", ".join(allowed) + f" (unknown key{hint})")
        return d

    def number(self, d: Mapping[str, Any], key: str, path: str, default: float | None,
               minimum: float | None = None) -> float:
        at = f"{path}.{key}" if path else key
        if key not in d:
            if default is None:
                raise self.fail(at, "a number (required key is missing)")
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
            raise self.fail(at, "a finite number", v)
        if minimum is not None and v < minimum:
            raise self.fail(at, f"a number >= {minimum}", v)
        return float(v)

    def scenario(self, d: Any) -> Scenario:
        """The whole scenario; every section is checked, and all their errors are raised together (one a line)."""
        if d is None:
            raise self.fail("", "a scenario mapping (the document is empty)")
        if not isinstance(d, Mapping):
            raise self.fail("", "a mapping", d)
        allowed = ("name", "home", "wind", "airframe", "params", "boot", "faults", "time_limit_s", "start_unix_s",
                   "radar", "targets", "intruders", "pilot", "ground_station", "camera_world", "camera", "birds",
                   "lighting", "retask")
        problems: list[str] = []

        def checked(read, *args, default=None):
            try:
                return read(*args)
            except ScenarioError as e:
                problems.append(str(e))
                return default

        for key in d:
            checked(self.mapping, {key: None}, "", allowed)
        top = {k: v for k, v in d.items() if k in allowed}
        name = top.get("name", "unnamed")
        if not isinstance(name, str) or not name:
            problems.append(str(self.fail("name", "a non-empty string", name)))
        home, heading = checked(self.home, top.get("home"), default=(None, 0.0))
        params = checked(self.params, top.get("params"), default={})
        targets = checked(self.targets, top.get("targets"), default=[])
        fields = dict(
            wind=checked(self.wind, top.get("wind")),
            airframe=checked(self.airframe, top.get("airframe")),
            params=params,
            boot=checked(self.boot, top.get("boot")),
            faults=checked(self.faults, top.get("faults")),
            time_limit_s=checked(self.number, top, "time_limit_s", "", 600.0, 0.0),
            start_unix_s=checked(self.number, top, "start_unix_s", "", DEFAULT_START_UNIX_S, 0.0),
            radar=checked(self.radar, top.get("radar")),
            targets=targets,
            pilot=checked(self.pilot, top.get("pilot")),
            ground_station=checked(self.ground_station, top.get("ground_station")),
            retasks=checked(self.retasks, top.get("retask"), default=()),
            camera_world=checked(self.camera_world, top.get("camera_world"), default=WorldSpec()),
            camera=checked(self.camera, top.get("camera"), default=OnboardCamera()),
            intruders=checked(self.intruders, top.get("intruders"), {t.name for t in targets},
                              int(params.get("SYSID_THISMAV", 1))),
        )
        intruder_names = ({i.name for i in fields["intruders"]} if fields["intruders"] is not None
                          else {i.get("name") for i in top.get("intruders") or () if isinstance(i, Mapping)})
        fields["birds"] = checked(self.birds, top.get("birds"), {t.name for t in targets} | intruder_names, default=())
        lighting = checked(self.lighting, top.get("lighting"))
        if lighting is not None and fields["camera_world"] is not None:
            fields["camera_world"] = dataclasses.replace(fields["camera_world"], lighting=lighting)
        if problems:
            raise ScenarioError("\n".join(problems))
        return Scenario(name=name, home=home, home_heading_deg=heading, **fields)

    def camera_world(self, d: Any) -> WorldSpec:
        if d is None:
            return WorldSpec()
        m = self.mapping(d, "camera_world", ("family", "seed", "clutter", "distractors", "effects"))
        family = m.get("family", "plain")
        if family not in ("plain", ANY_FAMILY) and family not in FAMILIES:
            raise self.fail("camera_world.family", f"one of plain, {ANY_FAMILY}, " + ", ".join(FAMILIES), family)
        seed = m.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            raise self.fail("camera_world.seed", "an integer >= 0, or null for the run's seed", seed)
        flags = {}
        for key in ("clutter", "distractors", "effects"):
            v = m.get(key, True)
            if not isinstance(v, bool):
                raise self.fail(f"camera_world.{key}", "true or false", v)
            flags[key] = v
        return WorldSpec(family, seed, **flags)

    def camera(self, d: Any) -> OnboardCamera:
        m = self.mapping(d, "camera", ("mount", "tilt_deg"))
        mount = m.get("mount", OnboardCamera.mount)
        if mount not in MOUNTS:
            raise self.fail("camera.mount", "one of " + ", ".join(MOUNTS), mount)
        tilt = self.number(m, "tilt_deg", "camera", OnboardCamera.tilt_deg)
        if not -90.0 < tilt < 90.0:
            raise self.fail("camera.tilt_deg", "a number in (-90, 90)", tilt)
        return OnboardCamera(mount, tilt)

    def home(self, d: Any) -> tuple[GeoPoint, float]:
        if d is None:
            raise self.fail("home", "a mapping with lat_deg, lon_deg, alt_m (required key is missing)")
        m = self.mapping(d, "home", ("lat_deg", "lon_deg", "alt_m", "heading_deg"))
        lat = self.number(m, "lat_deg", "home", None)
        lon = self.number(m, "lon_deg", "home", None)
        if not -90.0 <= lat <= 90.0:
            raise self.fail("home.lat_deg", "a latitude in [-90, 90]", lat)
        if not -180.0 <= lon <= 180.0:
            raise self.fail("home.lon_deg", "a longitude in [-180, 180]", lon)
        alt = self.number(m, "alt_m", "home", 0.0)
        heading = self.number(m, "heading_deg", "home", 0.0)
        return GeoPoint(lat, lon, alt), heading % 360.0

    def wind(self, d: Any) -> WindParams:
        m = self.mapping(d, "wind", ("speed_mps", "direction_deg", "gust_std_mps", "gust_tau_s"))
        w = WindParams()
        return WindParams(
            speed_mps=self.number(m, "speed_mps", "wind", w.speed_mps, minimum=0.0),
            direction_deg=self.number(m, "direction_deg", "wind", w.direction_deg),
            gust_std_mps=self.number(m, "gust_std_mps", "wind", w.gust_std_mps, minimum=0.0),
            gust_tau_s=self._positive(m, "gust_tau_s", "wind", w.gust_tau_s),
        )

    def _positive(self, m: Mapping[str, Any], key: str, path: str, default: float) -> float:
        v = self.number(m, key, path, default)
        if not v > 0.0:
            raise self.fail(f"{path}.{key}", "a number > 0", v)
        return v

    def airframe(self, d: Any) -> AirframeParams:
        fields = {f.name: f for f in dataclasses.fields(AirframeParams)}
        m = self.mapping(d, "airframe", tuple(fields))
        values: dict[str, Any] = {}
        for key in m:
            v = self.number(m, key, "airframe", None)
            if fields[key].type in ("int", int):
                if v != int(v):
                    raise self.fail(f"airframe.{key}", "an integer", m[key])
                v = int(v)
            values[key] = v
        try:
            return AirframeParams(**values)
        except ValueError as e:
            raise ScenarioError(f"{self.source}: airframe: {e}") from e

    def params(self, d: Any) -> dict[str, float]:
        if d is None:
            return {}
        if not isinstance(d, Mapping):
            raise self.fail("params", "a mapping of ArduCopter parameter names to numbers", d)
        known = ParamStore()
        out: dict[str, float] = {}
        for key in d:
            if not isinstance(key, str) or key not in known:
                raise self.fail(f"params.{key}", "a known ArduCopter parameter name (see sitl/vehicle/params.py)")
            out[key] = self.number(d, key, "params", None)
        return out

    def boot(self, d: Any) -> BootParams:
        m = self.mapping(d, "boot", ("gps_fix_s", "ekf_ready_s", "prearm_ok_s"))
        b = BootParams()
        gps = self.number(m, "gps_fix_s", "boot", b.gps_fix_s, minimum=0.0)
        ekf = self.number(m, "ekf_ready_s", "boot", b.ekf_ready_s, minimum=0.0)
        pre = self.number(m, "prearm_ok_s", "boot", b.prearm_ok_s, minimum=0.0)
        if ekf < gps:
            raise self.fail("boot.ekf_ready_s", f"a time >= boot.gps_fix_s ({gps})", ekf)
        if pre < ekf:
            raise self.fail("boot.prearm_ok_s", f"a time >= boot.ekf_ready_s ({ekf})", pre)
        return BootParams(gps, ekf, pre)

    def faults(self, d: Any) -> tuple[Fault, ...]:
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("faults", "a list of faults", d)
        out = []
        for i, item in enumerate(d):
            path = f"faults[{i}]"
            m = self.mapping(item, path, ("at_s", "kind", "duration_s"))
            if not isinstance(item, Mapping):
                raise self.fail(path, "a mapping", item)
            kind = m.get("kind")
            if kind not in FAULT_KINDS:
                raise self.fail(f"{path}.kind", "one of " + ", ".join(FAULT_KINDS), kind)
            at = self.number(m, "at_s", path, None, minimum=0.0)
            dur = None if m.get("duration_s") is None else self._positive(m, "duration_s", path, 0.0)
            out.append(Fault(at, kind, dur))
        return tuple(out)

    # -- radar and scripted targets (sitl/scenarios/README.md) --------------------------------

    _RADAR_KEYS = ("lat_deg", "lon_deg", "alt_m", "yaw_deg", "pitch_deg", "roll_deg", "fov_az_deg", "fov_el_deg",
                   "min_range_m", "max_range_m", "rate_hz", "sigma_range_m", "sigma_az_deg", "sigma_el_deg",
                   "sigma_vel_mps", "vel_tau_s", "pd", "coast_s", "confidence_tau_s", "failures", "clutter",
                   "off_at_s", "udp_host", "udp_port", "radar_id", "reference_rcs_m2", "pfa")

    def radar(self, d: Any) -> RadarConfig | None:
        if d is None:
            return None
        m = self.mapping(d, "radar", self._RADAR_KEYS)
        lat = self.number(m, "lat_deg", "radar", None)
        lon = self.number(m, "lon_deg", "radar", None)
        if not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 180.0:
            raise self.fail("radar.lat_deg/lon_deg", "a latitude in [-90, 90] and a longitude in [-180, 180]", (lat, lon))
        dflt = RadarConfig(GeoPoint(lat, lon))

        def num(key: str, default: float, minimum: float | None = None) -> float:
            return self.number(m, key, "radar", default, minimum)

        def angle(key: str, default_rad: float, minimum: float | None = None) -> float:
            return math.radians(self.number(m, key, "radar", math.degrees(default_rad), minimum))

        pd = num("pd", dflt.pd, 0.0)
        if pd > 1.0:
            raise self.fail("radar.pd", "a probability in [0, 1]", pd)
        rate = num("rate_hz", dflt.rate_hz)
        if not rate > 0.0:
            raise self.fail("radar.rate_hz", "a number > 0", rate)
        min_r, max_r = num("min_range_m", dflt.min_range_m, 0.0), num("max_range_m", dflt.max_range_m, 0.0)
        if max_r <= min_r:
            raise self.fail("radar.max_range_m", f"a range > radar.min_range_m ({min_r})", max_r)
        port = m.get("udp_port")
        if port is not None and (isinstance(port, bool) or not isinstance(port, int) or not 0 < port < 65536):
            raise self.fail("radar.udp_port", "a UDP port number 1..65535", port)
        host = m.get("udp_host", dflt.udp_host)
        if not isinstance(host, str) or not host:
            raise self.fail("radar.udp_host", "a host name or address", host)
        rid = m.get("radar_id", dflt.radar_id)
        if not isinstance(rid, str) or not rid:
            raise self.fail("radar.radar_id", "a non-empty string", rid)
        off = m.get("off_at_s")
        pfa = num("pfa", dflt.pfa)
        if not 0.0 < pfa < 1.0:
            raise self.fail("radar.pfa", "a false-alarm probability in (0, 1)", pfa)
        return RadarConfig(
            position=GeoPoint(lat, lon, num("alt_m", 0.0)),
            yaw_rad=angle("yaw_deg", 0.0), pitch_rad=angle("pitch_deg", 0.0), roll_rad=angle("roll_deg", 0.0),
            fov_az_rad=angle("fov_az_deg", dflt.fov_az_rad, 0.0), fov_el_rad=angle("fov_el_deg", dflt.fov_el_rad, 0.0),
            min_range_m=min_r, max_range_m=max_r, rate_hz=rate,
            sigma_range_m=num("sigma_range_m", dflt.sigma_range_m, 0.0),
            sigma_az_rad=angle("sigma_az_deg", dflt.sigma_az_rad, 0.0),
            sigma_el_rad=angle("sigma_el_deg", dflt.sigma_el_rad, 0.0),
            sigma_vel_mps=num("sigma_vel_mps", dflt.sigma_vel_mps, 0.0),
            vel_tau_s=self._positive(m, "vel_tau_s", "radar", dflt.vel_tau_s),
            pd=pd, coast_s=num("coast_s", dflt.coast_s, 0.0),
            confidence_tau_s=self._positive(m, "confidence_tau_s", "radar", dflt.confidence_tau_s),
            failures=self._radar_part(m.get("failures"), "radar.failures", RadarFailureRates),
            clutter=self._radar_part(m.get("clutter"), "radar.clutter", RadarClutter),
            off_at_s=None if off is None else num("off_at_s", 0.0, 0.0),
            reference_rcs_m2=self._positive(m, "reference_rcs_m2", "radar", dflt.reference_rcs_m2), pfa=pfa,
            udp_host=host, udp_port=port, radar_id=rid,
        )

    def _signature(self, d: Any, path: str) -> RadarSignature:
        """An object's own ``radar:`` mapping (rcs_m2, pd, drop_per_s)."""
        if not isinstance(d, Mapping):
            raise self.fail(path, "a mapping with rcs_m2, pd, drop_per_s", d)
        m = self.mapping(d, path, ("rcs_m2", "pd", "drop_per_s"))
        rcs = None if m.get("rcs_m2") is None else self._positive(m, "rcs_m2", path, 0.0)
        pd = None if m.get("pd") is None else self.number(m, "pd", path, None, 0.0)
        if pd is not None and pd > 1.0:
            raise self.fail(f"{path}.pd", "a probability in [0, 1]", pd)
        drop = None if m.get("drop_per_s") is None else self.number(m, "drop_per_s", path, None, 0.0)
        return RadarSignature(rcs, pd, drop)

    def _radar_part(self, d: Any, path: str, cls: type) -> Any:
        names = tuple(f.name for f in dataclasses.fields(cls))
        m = self.mapping(d, path, names)
        values = {k: self.number(m, k, path, None, 0.0) for k in m}
        if "swap_prob" in values and values["swap_prob"] > 1.0:
            raise self.fail(f"{path}.swap_prob", "a probability in [0, 1]", values["swap_prob"])
        return cls(**values)

    def targets(self, d: Any) -> tuple[ScriptedTarget, ...]:
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("targets", "a list of scripted targets", d)
        out, names = [], set()
        for i, item in enumerate(d):
            path = f"targets[{i}]"
            m = self.mapping(item, path, ("name", "kind") + self._SHAPES + ("start_s", "end_s", "radar"))
            name = m.get("name")
            if not isinstance(name, str) or not name or name == "ownship" or name in names:
                raise self.fail(f"{path}.name", "a unique non-empty name other than 'ownship'", name)
            names.add(name)
            shapes = [k for k in self._SHAPES if k in m]
            if len(shapes) != 1:
                raise self.fail(path, "exactly one of the keys " + ", ".join(self._SHAPES))
            kind = m.get("kind", "s1000")
            if kind not in TARGET_MODELS:
                raise self.fail(f"{path}.kind", "one of " + ", ".join(sorted(TARGET_MODELS)), kind)
            start = self.number(m, "start_s", path, 0.0, 0.0)
            end = None if m.get("end_s") is None else self.number(m, "end_s", path, None, start)
            shape = getattr(self, f"_{shapes[0]}")(m[shapes[0]], f"{path}.{shapes[0]}")
            radar = None
            if "radar" in m:
                if kind in RADAR_BLIND_KINDS:
                    raise self.fail(f"{path}.radar", f"no radar mapping: the radar does not see a {kind} target")
                radar = self._signature(m["radar"], f"{path}.radar")
            out.append(ScriptedTarget(name, shape, start, end, kind, radar))
        return tuple(out)

    _SHAPES = ("circle", "waypoints", "static")

    def _static(self, d: Any, path: str) -> StaticPoint:
        m = self.mapping(d, path, ("position_enu_m", "scatter_m", "heading_deg", "lying"))
        if "position_enu_m" not in m:
            raise self.fail(f"{path}.position_enu_m", "a list of 3 numbers (required key is missing)")
        lying = m.get("lying", False)
        if not isinstance(lying, bool):
            raise self.fail(f"{path}.lying", "true or false", lying)
        return StaticPoint(self._vector(m["position_enu_m"], f"{path}.position_enu_m"),
                           self.number(m, "scatter_m", path, 0.0, 0.0),
                           math.radians(self.number(m, "heading_deg", path, 0.0)), lying)

    def _vector(self, v: Any, path: str) -> tuple[float, float, float]:
        if (not isinstance(v, list) or len(v) != 3
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and _finite(x) for x in v)):
            raise self.fail(path, "a list of 3 finite numbers [east, north, up] (m)", v)
        return (float(v[0]), float(v[1]), float(v[2]))

    def _circle(self, d: Any, path: str) -> CirclePath:
        m = self.mapping(d, path, ("center_enu_m", "radius_m", "speed_mps", "clockwise", "phase_deg"))
        if "center_enu_m" not in m:
            raise self.fail(f"{path}.center_enu_m", "a list of 3 numbers (required key is missing)")
        cw = m.get("clockwise", False)
        if not isinstance(cw, bool):
            raise self.fail(f"{path}.clockwise", "true or false", cw)
        radius = self._positive(m, "radius_m", path, 50.0)
        return CirclePath(self._vector(m["center_enu_m"], f"{path}.center_enu_m"), radius,
                          self.number(m, "speed_mps", path, 5.0, 0.0), cw,
                          math.radians(self.number(m, "phase_deg", path, 0.0)))

    def _waypoints(self, d: Any, path: str) -> WaypointPath:
        m = self.mapping(d, path, ("points_enu_m", "speed_mps", "loop"))
        pts = m.get("points_enu_m")
        if not isinstance(pts, list) or len(pts) < 2:
            raise self.fail(f"{path}.points_enu_m", "a list of at least two [east, north, up] points", pts)
        loop = m.get("loop", False)
        if not isinstance(loop, bool):
            raise self.fail(f"{path}.loop", "true or false", loop)
        points = tuple(self._vector(v, f"{path}.points_enu_m[{k}]") for k, v in enumerate(pts))
        return WaypointPath(points, self._positive(m, "speed_mps", path, 5.0), loop)

    # -- the safety pilot's switch and the operator's ground station (sitl/scenarios/README.md) ----

    def pilot(self, d: Any) -> PilotScript | None:
        if d is None:
            return None
        m = self.mapping(d, "pilot", ("gate_channel", "gate", "on_pwm", "off_pwm", "events"))
        dflt = PilotScript()
        ints = {}
        for key, lo, hi in (("gate_channel", 5, 16), ("on_pwm", 800, 2200), ("off_pwm", 800, 2200)):
            v = m.get(key, getattr(dflt, key))
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise self.fail(f"pilot.{key}", f"an integer {lo}..{hi}", v)
            ints[key] = v
        if not ints["on_pwm"] > 1800 or not ints["off_pwm"] < 1200:
            raise self.fail("pilot.on_pwm/off_pwm", "on_pwm > 1800 and off_pwm < 1200 (ArduPilot's switch positions)",
                            (ints["on_pwm"], ints["off_pwm"]))
        events = m.get("events", [])
        if not isinstance(events, list):
            raise self.fail("pilot.events", "a list of {at_s, gate} events", events)
        out, last = [], -math.inf
        for i, item in enumerate(events):
            path = f"pilot.events[{i}]"
            e = self.mapping(item, path, ("at_s", "gate"))
            if not isinstance(item, Mapping):
                raise self.fail(path, "a mapping", item)
            at = self.number(e, "at_s", path, None, minimum=0.0)
            if at < last:
                raise self.fail(f"{path}.at_s", f"a time >= the previous event's ({last})", at)
            last = at
            out.append(PilotEvent(at, self._switch(e.get("gate"), f"{path}.gate")))
        return PilotScript(ints["gate_channel"], self._switch(m.get("gate", "on"), "pilot.gate"), ints["on_pwm"],
                           ints["off_pwm"], tuple(out))

    def _switch(self, v: Any, path: str) -> bool:
        # YAML 1.1 reads a bare on/off as a boolean; accept both spellings.
        if isinstance(v, bool):
            return v
        if v in ("on", "off"):
            return v == "on"
        raise self.fail(path, "on or off", v)

    def ground_station(self, d: Any) -> tuple[GroundStationEvent, ...]:
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("ground_station", "a list of {at_s, mode} events", d)
        out = []
        for i, item in enumerate(d):
            path = f"ground_station[{i}]"
            e = self.mapping(item, path, ("at_s", "mode"))
            if not isinstance(item, Mapping):
                raise self.fail(path, "a mapping", item)
            mode = e.get("mode")
            if mode not in GCS_MODES:
                raise self.fail(f"{path}.mode", "one of " + ", ".join(GCS_MODES), mode)
            out.append(GroundStationEvent(self.number(e, "at_s", path, None, minimum=0.0), mode))
        return tuple(sorted(out, key=lambda ev: ev.at_s))

    def retasks(self, d: Any) -> tuple[ScheduledRetask, ...]:
        """``retask: [{at_s, tree, subtree}]``: tree files relative to the scenario's folder (or shipped trees'
        names: ``sar``), existing, in time order; ``subtree`` (optional) names the subtree of the flying tree
        the file replaces."""
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("retask", "a list of {at_s, tree, subtree} entries", d)
        base = Path(self.source).parent if not self.source.startswith("<") else Path(".")
        out = []
        for i, item in enumerate(d):
            path = f"retask[{i}]"
            e = self.mapping(item, path, ("at_s", "tree", "subtree"))
            tree = e.get("tree")
            if not isinstance(tree, str) or not tree:
                raise self.fail(f"{path}.tree", "a tree file, relative to the scenario's folder, or a shipped tree's name",
                                tree)
            file = _retask_tree(base, tree)
            if file is None:
                raise self.fail(f"{path}.tree", f"an existing tree file (no {base / tree}) or a shipped tree's name", tree)
            subtree = e.get("subtree")
            if subtree is not None and (not isinstance(subtree, str) or not subtree.strip()):
                raise self.fail(f"{path}.subtree", "the tree ID of a subtree of the flying tree", subtree)
            out.append(ScheduledRetask(self.number(e, "at_s", path, None, minimum=0.0), file, subtree))
        return tuple(sorted(out, key=lambda r: r.at_s))

    # -- intruders: Phantom-like drones with their own MAVLink (sitl/world/intruders.py) ----------------

    _TRAJECTORY_KEYS = {
        "rectangle": ("corners_enu_m", "speed_mps", "pause_s"),
        "circle": ("center_enu_m", "radius_m", "speed_mps", "clockwise", "phase_deg"),
        "figure_eight": ("center_enu_m", "half_length_m", "speed_mps", "heading_deg"),
        "random_waypoints": ("center_enu_m", "half_extent_m", "alt_min_m", "alt_max_m", "speed_min_mps",
                             "speed_max_mps", "pause_max_s"),
        "evasive": ("center_enu_m", "half_extent_m", "alt_min_m", "alt_max_m", "cruise_speed_mps"),
    }

    def intruders(self, d: Any, taken: set[str], vehicle_sysid: int) -> tuple[IntruderSpec, ...]:
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("intruders", "a list of intruders", d)
        out, names, sysids = [], set(taken), {vehicle_sysid}
        for i, item in enumerate(d):
            path = f"intruders[{i}]"
            m = self.mapping(item, path, ("name", "sysid", "start_enu_m", "start_s", "telemetry_hz", "limits", "airframe",
                                          "radar", "manoeuvres") + TRAJECTORY_KINDS)
            name = m.get("name")
            if not isinstance(name, str) or not name or name == "ownship" or name in names:
                raise self.fail(f"{path}.name", "a name not used by another target or intruder, other than 'ownship'",
                                name)
            names.add(name)
            sysid = m.get("sysid", 2)
            if isinstance(sysid, bool) or not isinstance(sysid, int) or not 1 <= sysid <= 254 or sysid in sysids:
                raise self.fail(f"{path}.sysid", "a MAVLink system id 1..254 not used by the vehicle or another intruder",
                                sysid)
            sysids.add(sysid)
            if "start_enu_m" not in m:
                raise self.fail(f"{path}.start_enu_m", "a list of 3 numbers (required key is missing)")
            start = self._vector(m["start_enu_m"], f"{path}.start_enu_m")
            kinds = [k for k in TRAJECTORY_KINDS if k in m]
            if len(kinds) != 1:
                raise self.fail(path, "exactly one of the keys " + ", ".join(TRAJECTORY_KINDS))
            kind = kinds[0]
            params = self._trajectory(kind, m[kind], f"{path}.{kind}", start)
            lim = self.mapping(m.get("limits"), f"{path}.limits", tuple(f.name for f in dataclasses.fields(IntruderLimits)))
            dl = IntruderLimits()
            limits = IntruderLimits(**{k: self._positive(lim, k, f"{path}.limits", getattr(dl, k)) for k in dl.__dict__})
            airframe = m.get("airframe", "phantom")
            if airframe not in INTRUDER_AIRFRAMES:
                raise self.fail(f"{path}.airframe", "one of " + ", ".join(INTRUDER_AIRFRAMES), airframe)
            start_s = self.number(m, "start_s", path, 0.0, 0.0)
            manoeuvres = self._manoeuvres(m.get("manoeuvres"), f"{path}.manoeuvres", start_s, limits)
            radar = None if "radar" not in m else self._signature(m["radar"], f"{path}.radar")
            out.append(IntruderSpec(name, sysid, start, kind, params, start_s,
                                    self._positive(m, "telemetry_hz", path, 5.0), limits, airframe, manoeuvres, radar))
        return tuple(out)

    _MANOEUVRE_KEYS = {
        "turn": ("heading_deg", "duration_s", "speed_mps"),
        "dash": ("heading_deg", "duration_s", "speed_mps"),
        "climb": ("to_alt_m", "duration_s", "speed_mps"),
        "dive": ("to_alt_m", "duration_s", "speed_mps"),
    }
    _MANOEUVRE_REQUIRED = {"turn": ("heading_deg", "duration_s"), "dash": ("heading_deg", "duration_s"),
                           "climb": ("to_alt_m",), "dive": ("to_alt_m",)}

    def _manoeuvres(self, d: Any, path: str, start_s: float, limits: IntruderLimits) -> tuple[Manoeuvre, ...]:
        """An intruder's ``manoeuvres``: in time order, none before it starts, none overlapping the last one's duration."""
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail(path, "a list of manoeuvres {at_s, kind, ...}", d)
        out: list[Manoeuvre] = []
        for i, item in enumerate(d):
            at = f"{path}[{i}]"
            if not isinstance(item, Mapping):
                raise self.fail(at, "a mapping", item)
            kind = item.get("kind")
            if kind not in MANOEUVRE_KINDS:
                raise self.fail(f"{at}.kind", "one of " + ", ".join(MANOEUVRE_KINDS), kind)
            m = self.mapping(item, at, ("at_s", "kind") + self._MANOEUVRE_KEYS[kind])
            for key in self._MANOEUVRE_REQUIRED[kind]:
                if key not in m:
                    raise self.fail(f"{at}.{key}", f"a number (required for a {kind})")
            t0 = self.number(m, "at_s", at, None, 0.0)
            if t0 < start_s:
                raise self.fail(f"{at}.at_s", f"a time >= the intruder's start_s ({start_s})", t0)
            prev = out[-1] if out else None
            if prev is not None and prev.end_s is not None and t0 < prev.end_s:
                raise self.fail(f"{at}.at_s", f"a time >= the end of the previous manoeuvre ({prev.end_s})", t0)
            if prev is not None and t0 <= prev.at_s:
                raise self.fail(f"{at}.at_s", f"a time after the previous manoeuvre's at_s ({prev.at_s})", t0)
            dur = None if m.get("duration_s") is None else self._positive(m, "duration_s", at, 0.0)
            speed = None if m.get("speed_mps") is None else self._positive(m, "speed_mps", at, 0.0)
            limit = {"turn": limits.speed_h_mps, "dash": limits.speed_h_mps, "climb": limits.speed_up_mps,
                     "dive": limits.speed_down_mps}[kind]
            if speed is not None and speed > limit:
                raise self.fail(f"{at}.speed_mps", f"a speed <= the intruder's limit ({limit} m/s)", speed)
            heading = None if "heading_deg" not in m else self.number(m, "heading_deg", at, None)
            alt = None if "to_alt_m" not in m else self.number(m, "to_alt_m", at, None, 0.0)
            out.append(Manoeuvre(t0, kind, dur, heading, speed, alt))
        return tuple(out)

    # -- birds near a target, and the light (sitl/scenarios/README.md) -----------------------------------

    def birds(self, d: Any, names: set[str]) -> tuple[BirdSpec, ...]:
        if d is None:
            return ()
        if not isinstance(d, list):
            raise self.fail("birds", "a list of birds {near, offset_enu_m, ...}", d)
        out = []
        for i, item in enumerate(d):
            path = f"birds[{i}]"
            if not isinstance(item, Mapping):
                raise self.fail(path, "a mapping", item)
            m = self.mapping(item, path, ("near", "offset_enu_m", "count", "spread_m", "speed_mps", "start_s", "end_s",
                                          "radar"))
            near = m.get("near")
            if not isinstance(near, str) or near not in names:
                known = ", ".join(sorted(n for n in names if isinstance(n, str))) or "none in this scenario"
                raise self.fail(f"{path}.near", f"the name of a target or intruder ({known})", near)
            if "offset_enu_m" not in m:
                raise self.fail(f"{path}.offset_enu_m", "a list of 3 numbers (required key is missing)")
            offset = self._vector(m["offset_enu_m"], f"{path}.offset_enu_m")
            count = m.get("count", 1)
            if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_FLOCK:
                raise self.fail(f"{path}.count", f"an integer 1..{MAX_FLOCK}", count)
            start = self.number(m, "start_s", path, 0.0, 0.0)
            end = None if m.get("end_s") is None else self.number(m, "end_s", path, None, start)
            radar = None if "radar" not in m else self._signature(m["radar"], f"{path}.radar")
            out.append(BirdSpec(near, offset, count, self._positive(m, "spread_m", path, 5.0),
                                self._positive(m, "speed_mps", path, 8.0), start, end, radar))
        return tuple(out)

    def lighting(self, d: Any) -> LightingOverride | None:
        if d is None:
            return None
        if not isinstance(d, Mapping):
            raise self.fail("lighting", "a mapping with sun_elevation_deg, sun_azimuth_deg, overcast", d)
        m = self.mapping(d, "lighting", ("sun_elevation_deg", "sun_azimuth_deg", "overcast"))
        el = None if "sun_elevation_deg" not in m else self.number(m, "sun_elevation_deg", "lighting", None)
        if el is not None and not 0.0 <= el <= 90.0:
            raise self.fail("lighting.sun_elevation_deg", "an elevation in [0, 90]", el)
        az = None if "sun_azimuth_deg" not in m else self.number(m, "sun_azimuth_deg", "lighting", None)
        overcast = None if "overcast" not in m else self.number(m, "overcast", "lighting", None, 0.0)
        if overcast is not None and overcast > 1.0:
            raise self.fail("lighting.overcast", "a number in [0, 1] (0 clear, 1 fully overcast)", overcast)
        if el is None and az is None and overcast is None:
            return None
        return LightingOverride(el, None if az is None else az % 360.0, overcast)

    def _trajectory(self, kind: str, d: Any, path: str, start: tuple[float, float, float]) -> dict:
        m = self.mapping(d, path, self._TRAJECTORY_KEYS[kind])
        p: dict[str, Any] = {}
        if "center_enu_m" in m:
            p["center"] = self._vector(m["center_enu_m"], f"{path}.center_enu_m")
        for key in m:
            if key in ("center_enu_m", "corners_enu_m", "clockwise", "phase_deg", "heading_deg"):
                continue
            if key in ("pause_s", "pause_max_s", "alt_min_m"):
                p[key] = self.number(m, key, path, 0.0, 0.0)
            else:
                p[key] = self._positive(m, key, path, 1.0)
        if kind == "rectangle":
            pts = m.get("corners_enu_m")
            if not isinstance(pts, list) or len(pts) < 2:
                raise self.fail(f"{path}.corners_enu_m", "a list of at least two [east, north, up] corners", pts)
            p["corners"] = tuple(self._vector(v, f"{path}.corners_enu_m[{k}]") for k, v in enumerate(pts))
        if kind == "circle":
            cw = m.get("clockwise", False)
            if not isinstance(cw, bool):
                raise self.fail(f"{path}.clockwise", "true or false", cw)
            p["clockwise"] = cw
            c = p.get("center", start)
            p["phase_rad"] = math.radians(self.number(m, "phase_deg", path, math.degrees(
                math.atan2(start[1] - c[1], start[0] - c[0]))))
        if kind == "figure_eight":
            p["heading_rad"] = math.radians(self.number(m, "heading_deg", path, 0.0))
        for lo, hi in (("alt_min_m", "alt_max_m"), ("speed_min_mps", "speed_max_mps")):
            if lo in m and hi in m and m[lo] > m[hi]:
                raise self.fail(f"{path}.{hi}", f"a number >= {path}.{lo} ({m[lo]})", m[hi])
        return p

