"""ArduPilot's own ArduCopter SITL flying inside our world.

:mod:`sitl.ardupilot.process` finds and starts the ``arducopter`` binary with an external physics
backend (``--model JSON``); :mod:`sitl.ardupilot.simulator` is that backend: our rotor-body physics,
wind, the scenario's intruders and radar, and the pilot's RC, on ArduCopter's physics clock, with
the same face as the built-in :class:`sitl.simulator.Simulator` so a rehearsal can fly either.
"""
