"""The simulated world and its sensors: the scenario file, intruding drones with their own
telemetry, scripted targets (people, drones on paths), the ground radar and the rendered camera.

The world may use the vehicle's configuration types (airframe, parameters, wind) but never the
rehearsal bench or the mission.
"""
