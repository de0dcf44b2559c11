"""The rehearsal bench: flies a mission tree against the simulator through a real vehicle link and
scores it against the ground truth.

Rehearsals (:mod:`~sitl.bench.rehearsal`) over the in-process vehicle
(:mod:`~sitl.bench.in_process`), the mission's sensors wired to the simulated ones
(:mod:`~sitl.bench.sensors`), scoring (:mod:`~sitl.bench.scoring`, :mod:`~sitl.bench.sar_scoring`),
reports, campaigns over many seeds, and trials: the paper's radar flights, the search-only trial,
the follow evaluation and the camera datasets the detector is trained and scored on.
"""
