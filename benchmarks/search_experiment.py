"""Search experiments: a kinematic chaser flying the planners against a simulated target.

Used by bench_search.py, search_belief_gain.py and search_open_question.py. For speed over many
seeds this is not the MAVLink simulator: the chaser is a speed- and acceleration-limited point
mass flying each set-point, level, facing along the planned heading; the target is simulated here
(random walk, velocity-holding around buildings, or road-bound) and seen by the same
CameraModel with probability p_detect per look. The mission side (belief, dynamics, sensor model,
planners, SearchSession) is exactly the code the behaviours run. Scoring reads the target's truth.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from chaser_bt.cue import TargetCue  # noqa: E402
from chaser_bt.search import (BeliefGrid, GaussianDynamics, GridSpec, MaxBeliefPlanner, RecedingHorizonPlanner,  # noqa: E402
                              SearchSession, SensorModel, VelocityDynamics, box_mask, corridor_mask, level_attitude)
from chaser_bt.vision import CameraModel  # noqa: E402

DT = 0.5  # s per simulation step (one look per step)
CHASER_SPEED, CHASER_ACCEL = 12.0, 4.0
ROADS = [-400.0, -200.0, 0.0, 200.0, 400.0]  # a Manhattan road grid: x = c and y = c lines
BUILDINGS = [((-160.0, 40.0, 0.0), (-60.0, 140.0, 200.0)), ((40.0, -140.0, 0.0), (140.0, -40.0, 200.0)),
             ((40.0, 60.0, 0.0), (120.0, 160.0, 200.0)), ((-150.0, -150.0, 0.0), (-70.0, -50.0, 200.0))]


@dataclass
class World:
    """The terrain the target lives in: which cells it may occupy, and how it moves."""

    kind: str  # "open" | "buildings" | "road"
    spec: GridSpec
    nogo: np.ndarray
    rng: np.random.Generator
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def allowed(self, p: np.ndarray) -> bool:
        idx, inside = self.spec.index_of(p)
        return bool(inside[0]) and not self.nogo[tuple(idx[0])]

    def start(self) -> None:
        r = self.rng
        if self.kind == "road":
            self.pos = np.array([r.choice(ROADS[1:-1]), r.uniform(-150, 150), 20.0])
            heading = r.choice([np.array([0.0, 1.0]), np.array([0.0, -1.0])])
            self.vel = np.array([*heading * 8.0, 0.0])
            return
        while True:
            self.pos = np.array([r.uniform(-150, 150), r.uniform(-150, 150), r.uniform(40, 100)])
            if self.allowed(self.pos):
                break
        ang = r.uniform(-math.pi, math.pi)
        speed = 6.0 if self.kind == "buildings" else 4.0
        self.vel = np.array([speed * math.cos(ang), speed * math.sin(ang), 0.0])

    def step(self, dt: float) -> None:
        r = self.rng
        if self.kind == "road":
            nxt = self.pos + self.vel * dt
            for c in ROADS:  # at a crossing: straight on, left or right
                along = 0 if self.vel[0] else 1
                if (self.pos[along] - c) * (nxt[along] - c) < 0 and abs(self.pos[1 - along] - round(self.pos[1 - along] / 200) * 200) < 1:
                    nxt[along] = c
                    turn = r.integers(3)
                    if turn:
                        v = np.zeros(3)
                        v[1 - along] = 8.0 * (1 if turn == 1 else -1)
                        self.vel = v
                    break
            if np.any(np.abs(nxt[:2]) > 400):
                self.vel = -self.vel
                nxt = self.pos + self.vel * dt
            self.pos = nxt
            return
        if self.kind == "open":  # random walk: Ornstein-Uhlenbeck velocity, about 10 m/s at most
            self.vel += -self.vel * dt / 10.0 + r.normal(0, [1.2, 1.2, 0.5]) * math.sqrt(dt)
            h = np.hypot(*self.vel[:2])
            if h > 10.0:
                self.vel[:2] *= 10.0 / h
            self.vel[2] = np.clip(self.vel[2], -5, 5)
        else:  # holds its velocity (small wander), turns away from buildings
            self.vel[:2] += r.normal(0, 0.15, 2) * math.sqrt(dt)
            self.vel[2] = 0.0
        nxt = self.pos + self.vel * dt
        tries = 0
        while not self.allowed(nxt) or not 20 <= nxt[2] <= 180:
            ang = r.choice([-1, 1]) * math.pi / 2 if tries < 4 else math.pi
            c, s = math.cos(ang), math.sin(ang)
            self.vel[:2] = [c * self.vel[0] - s * self.vel[1], s * self.vel[0] + c * self.vel[1]]
            self.vel[2] = -self.vel[2]
            nxt = self.pos + self.vel * dt
            tries += 1
            if tries > 8:
                nxt = self.pos
                break
        self.pos = nxt


def make_world(kind: str, spec: GridSpec, rng: np.random.Generator) -> World:
    nogo = np.zeros(spec.shape, bool)
    if kind == "buildings":
        for lo, hi in BUILDINGS:
            nogo |= box_mask(spec, lo, hi)
    elif kind == "road":
        road = np.zeros(spec.shape, bool)
        for c in ROADS:
            road |= corridor_mask(spec, [(c, -400), (c, 400)], 10.0, 20.0) | corridor_mask(spec, [(-400, c), (400, c)], 10.0, 20.0)
        nogo = ~road
    return World(kind, spec, nogo, rng)


@dataclass
class Run:
    t_acquire_s: float | None
    gains: list[float]
    plan_ms: list[float]


def fly(planner_name: str, kind: str, seed: int, *, horizon: int = 5, gamma: float = 0.9, camera_on: bool = True,
        duration_s: float = 180.0, model_aware: bool = True) -> Run:
    """One search: target lost when the chaser is 200 m from it; fly until acquired or ``duration_s``."""
    import time

    # Separate streams: the target's path depends on the seed only, never on the planner.
    rng, detect_rng = np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2])
    spec = GridSpec.around((0.0, 0.0, 0.0))
    world = make_world(kind, spec, np.random.default_rng([seed, 0]))
    world.start()
    camera = CameraModel()
    # The radar's last fix: range/azimuth/elevation noise of about 5 m / 1 deg at a few hundred metres.
    cov = np.diag([8.0, 8.0, 5.0]) ** 2
    fix = np.clip(world.pos + rng.multivariate_normal(np.zeros(3), cov), [-400, -400, 0], [400, 400, 200])
    vel_est = world.vel + rng.normal(0, 1.0, 3) * np.array([1, 1, 0.3])
    cue = TargetCue(0.0, fix, cov, velocity_enu=vel_est, source="radar")
    bearing = rng.uniform(-math.pi, math.pi)
    chaser = np.array([fix[0] + 200 * math.cos(bearing), fix[1] + 200 * math.sin(bearing), 60.0])
    chaser = np.clip(chaser, [-400, -400, 0], [400, 400, 200])
    chaser_v = np.zeros(3)
    yaw = math.atan2(fix[1] - chaser[1], fix[0] - chaser[0])

    nogo = world.nogo if model_aware else np.zeros(spec.shape, bool)
    belief = BeliefGrid.from_cue(spec, cue, nogo)
    if model_aware and kind == "buildings":
        dynamics = VelocityDynamics(vel_est, sigma_v_h_mps=2.0, sigma_v_v_mps=1.0)
    elif model_aware and kind == "road":
        dynamics = GaussianDynamics(v_h_mps=8.0, v_v_mps=0.0)
    else:
        dynamics = GaussianDynamics()
    sensor = SensorModel(camera, spec)
    planner = RecedingHorizonPlanner(sensor, horizon, gamma) if planner_name == "rhc" else MaxBeliefPlanner(spec)
    # The chaser may overfly roads and buildings alike (no-go constrains the target only).
    session = SearchSession(belief, dynamics, sensor, planner, 0.0, blocked=np.zeros(spec.shape, bool))

    gains, plan_ms, t = [], [], 0.0
    while t < duration_s:
        t0 = time.perf_counter()
        snap = session.update(t, chaser, level_attitude(yaw), yaw)
        if snap.replanned:
            plan_ms.append(1e3 * (time.perf_counter() - t0))
        gains.append(snap.gain)
        if camera_on and camera.visible(world.pos[None], chaser, level_attitude(yaw))[0] and detect_rng.random() < camera.p_detect:
            return Run(t, gains, plan_ms)
        # Kinematic chaser: accelerate towards the set-point, arrive without overshoot.
        to_go = snap.target_enu - chaser
        dist = float(np.linalg.norm(to_go))
        v_des = to_go / dist * min(CHASER_SPEED, math.sqrt(2 * CHASER_ACCEL * dist)) if dist > 1e-6 else np.zeros(3)
        dv = v_des - chaser_v
        n = float(np.linalg.norm(dv))
        chaser_v = chaser_v + (dv if n <= CHASER_ACCEL * DT else dv / n * CHASER_ACCEL * DT)
        chaser = chaser + chaser_v * DT
        if snap.yaw_enu_rad is not None:
            yaw = snap.yaw_enu_rad
        world.step(DT)
        t += DT
    return Run(None, gains, plan_ms)
