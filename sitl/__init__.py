"""The built-in simulator and the rehearsal bench: two houses with one door between them.

The simulator is what a real aircraft and its field would be:

- :mod:`sitl.vehicle`: the simulated ArduCopter, from the physics up through the autopilot and its
  modes to the MAVLink face a ground station talks to;
- :mod:`sitl.world`: what it flies in and what its sensors see: the scenario, intruders, scripted
  targets, the ground radar and the rendered camera;
- :mod:`sitl.simulator` steps both on one clock; :mod:`sitl.server` puts it on the network
  (:mod:`sitl.transports`), so ``chaser-bt run`` flies it as it would fly ArduPilot.

:mod:`sitl.bench` flies missions against the simulator and scores them: rehearsals, the sensor
wiring, scoring, reports, campaigns and trials. It alone reads the simulator's ground truth, and
only to score.

The simulator meets the mission only where a real aircraft would: encoded MAVLink, radar
datagrams, camera frames and target telemetry. It imports ``chaser_bt``'s geodesy and shared value
types, never the bench, ``behaviours`` or the mission side of ``chaser_bt``. The import-linter
contracts in ``pyproject.toml`` hold that line; ``tests/test_architecture.py`` runs them.
"""
