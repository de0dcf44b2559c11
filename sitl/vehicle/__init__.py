"""The simulated aircraft: airframe and physics, the ArduCopter autopilot and its flight modes,
parameters, telemetry and the MAVLink endpoint (physics -> autopilot -> MAVLink face).

Nothing here knows the world file it was described in: the autopilot is started with a
:class:`~sitl.vehicle.setup.VehicleSetup`, which a scenario happens to be.
"""
