"""Birds near a target: where they fly, one radar object a flock, drawn by the camera where the radar has them."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from chaser_bt.radar.stream import RadarStreamReader
from chaser_bt.vision.camera import CameraModel
from sitl.simulator import Simulator
from sitl.world.camera.frame_source import SimTarget, SimulatorFrameSource
from sitl.world.intruders import BirdSpec
from sitl.world.radar.config import RadarSignature
from sitl.world.scenario import Scenario, ScenarioError

DOC = """
name: birds
home: {lat_deg: 42.5445, lon_deg: -71.6105, alt_m: 80.0}
radar: {lat_deg: 42.5440, lon_deg: -71.6105, alt_m: 81.0, pitch_deg: 10}
targets:
  - {name: hover, static: {position_enu_m: [0, 100, 20]}}
intruders:
  - {name: p, sysid: 2, start_enu_m: [40, 150, 25], circle: {center_enu_m: [0, 150, 25], radius_m: 40}}
birds:
  - {near: hover, offset_enu_m: [6, 0, 3], spread_m: 4, speed_mps: 8}
  - {near: p, offset_enu_m: [-10, 5, 2], count: 12, spread_m: 3, start_s: 2, end_s: 8, radar: {rcs_m2: 0.004}}
"""


def scenario(doc: str = DOC, **edit) -> Scenario:
    d = yaml.safe_load(doc)
    for k, v in edit.items():
        d["birds"][int(k[1:])].update(v)
    return Scenario.from_dict(d, "<b>")


def test_birds_parse_with_their_defaults():
    s = scenario()
    assert s.birds[0] == BirdSpec("hover", (6.0, 0.0, 3.0), 1, 4.0, 8.0, 0.0, None, None)
    assert s.birds[1] == BirdSpec("p", (-10.0, 5.0, 2.0), 12, 3.0, 8.0, 2.0, 8.0, RadarSignature(0.004))
    assert s.birds[1].flock_signature == RadarSignature(0.048)  # 12 birds' cross-sections add
    assert Scenario.from_dict({"home": {"lat_deg": 1, "lon_deg": 2}}).birds == ()


def test_a_bird_circles_its_station_point_by_a_static_target():
    sim = Simulator(scenario(), 1)
    station = np.array([6.0, 100.0, 23.0])
    pos, vel, times = [], [], []
    period = 2 * math.pi * 4.0 / 8.0  # radius 4 m at 8 m/s
    while sim.time_s < 3 * period:
        sim.step()
        p, v = sim.radar_objects()["bird-hover-0"]
        pos.append(p)
        vel.append(v)
        times.append(sim.time_s)
    pos, vel = np.array(pos), np.array(vel)
    assert np.allclose(np.linalg.norm(pos[:, :2] - station[:2], axis=1), 4.0) and np.allclose(pos[:, 2], 23.0)
    assert np.allclose(np.linalg.norm(vel, axis=1), 8.0)
    whole = np.array(times) > np.array(times)[-1] - 2 * period  # two whole turns: the mean is the station point
    assert np.allclose(pos[whole].mean(axis=0), station, atol=0.15)


def test_a_flock_is_one_radar_object_at_its_birds_centre_near_the_intruder():
    sim = Simulator(scenario(), 1)
    sim.run_until(1.0)
    assert "bird-p-1" not in sim.radar_objects() and len(sim.surroundings.bird_poses(sim.time_s)) == 1  # not yet
    sim.run_until(5.0)
    objs = sim.radar_objects()
    flock = [k for k in objs if k.startswith("bird")]
    assert sorted(flock) == ["bird-hover-0", "bird-p-1"]  # one object for twelve birds
    centre, _ = objs["bird-p-1"]
    station = sim.intruders[0].pos + np.array([-10.0, 5.0, 2.0])
    assert math.hypot(*(centre - station)[:2]) == pytest.approx(3.0) and centre[2] == pytest.approx(station[2])
    poses = sim.surroundings.bird_poses(sim.time_s)  # the lone bird's, then the flock's twelve
    assert len(poses) == 13
    birds = poses[1:]
    assert np.allclose(np.mean([b.position_enu for b in birds], axis=0), centre)
    assert sim.radar.signatures == {"bird-p-1": RadarSignature(0.048)}
    labels = set(sim.radar_truth.labels.values())
    assert {"hover", "p", "bird-hover-0"} <= labels
    sim.run_until(9.0)
    assert "bird-p-1" not in sim.radar_objects()  # gone at end_s


def test_radar_birds_are_low_confidence_tracks():
    sim = Simulator(scenario(), 1)
    q = []
    sim.add_radar_consumer(q.append)
    sim.run_until(6.0)
    scan = RadarStreamReader().accept_all(q)[-1]
    conf = {sim.radar_truth.labels[t.track_id]: t.confidence for t in scan.tracks}
    assert conf["bird-hover-0"] <= 0.6 < conf["hover"]


def test_birds_draw_from_streams_of_their_own():
    plain = yaml.safe_load(DOC)
    del plain["birds"]
    a, b = Simulator(Scenario.from_dict(plain), 3), Simulator(scenario(), 3)
    a.run_until(6.0)
    b.run_until(6.0)
    assert np.array_equal(a.intruders[0].pos, b.intruders[0].pos)
    assert np.array_equal(a.truth.pos_enu, b.truth.pos_enu)


def test_the_camera_draws_the_bird_where_the_radar_has_it_and_labels_stay():
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    doc = yaml.safe_load(DOC)
    doc["targets"] = [{"name": "hover", "static": {"position_enu_m": [0, 25, 2]}}]  # ahead of the parked chaser
    doc["intruders"] = []
    doc["birds"] = [{"near": "hover", "offset_enu_m": [4, 0, 0.5], "spread_m": 0.5, "speed_mps": 0.2}]
    with_birds = Scenario.from_dict(doc)
    without = Scenario.from_dict({k: v for k, v in doc.items() if k != "birds"})
    frames, shots = [], []
    for sc in (with_birds, without):
        sim = Simulator(sc, 0)
        sim.run_until(0.5)
        src = SimulatorFrameSource(sim, cam, [SimTarget("s1000", sc.targets[0].path)], seed=1)
        shot = src.shot(0.5)
        frames.append((src.develop(shot), src.last_labels))
        shots.append((shot, sim))
    (img_b, labels_b), (img_0, labels_0) = frames
    assert labels_b == labels_0 and [lab.index for lab in labels_b] == [0]  # the target's label, unmoved
    shot, sim = shots[0]
    assert shots[1][0].birds == ()
    (bird,) = shot.birds
    assert bird.position_enu == tuple(sim.radar_objects()["bird-hover-0"][0])  # camera and radar: one place
    px, _ = cam.project(np.array([bird.position_enu]), sim.truth.pos_enu, sim.truth.attitude)
    x, y = (int(round(c)) for c in px[0])
    diff = np.abs(img_b.image.astype(int) - img_0.image.astype(int)).sum(axis=2)
    assert diff[max(y - 6, 0):y + 7, max(x - 10, 0):x + 11].max() > 60  # the bird is drawn there
    far = diff.copy()
    far[max(y - 24, 0):y + 25, max(x - 24, 0):x + 25] = 0
    assert far.max() == 0  # and nowhere else


@pytest.mark.parametrize("edit, path, expected", [
    ({"near": "nobody"}, "birds[0].near", "target or intruder (hover, p)"),
    ({"count": 31}, "birds[0].count", "integer 1..30"),
    ({"count": 0}, "birds[0].count", "integer 1..30"),
    ({"offset_enu_m": [1, 2]}, "birds[0].offset_enu_m", "3 finite numbers"),
    ({"spread_m": 0}, "birds[0].spread_m", "> 0"),
    ({"speed_mps": -1}, "birds[0].speed_mps", "> 0"),
    ({"radar": {"rcs_m2": -0.01}}, "birds[0].radar.rcs_m2", "> 0"),
    ({"wingspan": 1}, "birds[0].wingspan", "unknown key"),
    ({"start_s": 5, "end_s": 2}, "birds[0].end_s", ">= 5.0"),
])
def test_bad_birds_name_their_key_path(edit, path, expected):
    with pytest.raises(ScenarioError) as e:
        scenario(b0=edit)
    assert str(e.value).startswith(f"<b>: {path}") and expected in str(e.value)


def test_birds_need_an_offset_and_a_list():
    d = yaml.safe_load(DOC)
    del d["birds"][0]["offset_enu_m"]
    with pytest.raises(ScenarioError, match=r"<b>: birds\[0\]\.offset_enu_m: expected .*required"):
        Scenario.from_dict(d, "<b>")
    d["birds"] = {"near": "p"}
    with pytest.raises(ScenarioError, match=r"<b>: birds: expected a list"):
        Scenario.from_dict(d, "<b>")
