"""The sensor model S: which grid cells the camera would detect the target in (paper section 3.4).

``S(x_t, yaw)`` at the vehicle's real pose lowers the belief where the camera looked and saw
nothing (:meth:`SensorModel.observe`). In the planner's prediction ``S(x_t, x_t-1)`` puts the
vehicle at a cell centre, level, facing along its last horizontal move; there the footprint is
the same set of cell offsets at every cell, so it is computed once per heading
(:meth:`SensorModel.stencil`) and translated.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.search.belief import BeliefGrid, GridSpec
from chaser_bt.vision.camera import CameraModel

__all__ = ["SensorModel", "level_attitude"]


def level_attitude(yaw_enu_rad: float) -> Rotation:
    """FLU body -> ENU for a level vehicle facing ``yaw_enu_rad`` (counter-clockwise from east)."""
    return Rotation.from_euler("z", yaw_enu_rad)


class SensorModel:
    """The camera's detection footprint over a grid.

    Args:
        camera: the camera (FOV, mount, detection range, detection probability).
        spec: the belief grid.
    """

    def __init__(self, camera: CameraModel, spec: GridSpec) -> None:
        self.camera = camera
        self.spec = spec
        reach = camera.max_range_m + float(np.linalg.norm(camera.offset_body_m))
        self._reach_cells = int(math.ceil(reach / spec.spacing_m))

    @property
    def reach_cells(self) -> int:
        """Cells from the camera to the farthest cell it can see, per axis."""
        return self._reach_cells

    @property
    def p_detect(self) -> float:
        return self.camera.p_detect

    def footprint(self, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """Flat indices of the cells whose centres the camera sees from this pose."""
        spec, r = self.spec, self._reach_cells
        idx, _ = spec.index_of(vehicle_pos_enu)
        lo = np.maximum(idx[0] - r - 1, 0)
        hi = np.minimum(idx[0] + r + 2, spec.shape)
        axes = [np.arange(lo[a], hi[a]) for a in range(3)]
        cells = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        seen = self.camera.visible(spec.center_of(cells), vehicle_pos_enu, body_attitude)
        return np.ravel_multi_index(tuple(cells[seen].T), spec.shape)

    def observe(self, belief: BeliefGrid, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> float:
        """Apply S at a real pose; returns the belief gain: the detection probability given not yet seen."""
        total = belief.total()
        removed = belief.observe(self.footprint(vehicle_pos_enu, body_attitude), self.camera.p_detect)
        return removed / total if total > 0 else 0.0

    def gain(self, belief: BeliefGrid, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> float:
        """Belief gain at a pose without changing the belief (the paper's plotted quantity)."""
        cells = self.footprint(vehicle_pos_enu, body_attitude)
        return float(self.camera.p_detect * belief.p.reshape(-1)[cells].sum() / belief.total())

    def stencil(self, yaw_enu_rad: float) -> np.ndarray:
        """Cell offsets (m, 3) seen from a cell centre, level, facing ``yaw_enu_rad``."""
        r = self._reach_cells
        rng = np.arange(-r, r + 1)
        offsets = np.stack(np.meshgrid(rng, rng, rng, indexing="ij"), axis=-1).reshape(-1, 3)
        seen = self.camera.visible(offsets * self.spec.spacing_m, np.zeros(3), level_attitude(yaw_enu_rad))
        return offsets[seen]
