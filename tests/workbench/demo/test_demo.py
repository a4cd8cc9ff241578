"""The demo generator: deterministic, all six terrains, real ROS 2 MCAP at two rates, truth sidecars."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from workbench.demo import FOOT_HZ, IMU_HZ, TERRAINS, RunConditions, generate_demo_logs, generate_walk
from workbench.demo.ground_camera import CAMERA_FPS, HEIGHT, ground_frames, terrain_tile


def test_same_seed_same_walk_other_seed_other_walk() -> None:
    a, b, c = generate_walk(5, 60.0), generate_walk(5, 60.0), generate_walk(6, 60.0)
    np.testing.assert_array_equal(a.forces, b.forces)
    assert a.truth == b.truth
    assert not np.allclose(a.forces, c.forces)


def test_each_walk_is_a_run_of_its_own_on_the_same_terrain_patches() -> None:
    nominal, run = generate_walk(3, 60.0, conditions=RunConditions()), generate_walk(3, 60.0)
    assert run.truth == nominal.truth  # the run's conditions come from a stream of their own
    conditions = RunConditions.draw(3)
    assert conditions != RunConditions.draw(4) and conditions.speed != 1.0
    np.testing.assert_allclose(run.distance[-1] / nominal.distance[-1], conditions.speed, rtol=1e-9)
    gravity = run.accel.mean(0) / np.linalg.norm(run.accel.mean(0))  # the mounting tilts gravity off the IMU's z
    tilt = np.degrees(np.arccos(gravity[2]))
    expected = np.degrees(np.hypot(*conditions.mount_rad))
    assert abs(tilt - expected) < 1.0, (tilt, expected)
    np.testing.assert_allclose(np.linalg.norm(run.quat, axis=1), 1.0, atol=1e-9)
    ratio = run.forces[:, :, 2].sum(0) / nominal.forces[:, :, 2].sum(0)  # per foot: its sensor's gain
    np.testing.assert_allclose(ratio, conditions.force_gain, rtol=1e-3)


def test_every_walk_visits_all_six_terrains_in_patches_of_varied_length() -> None:
    walk = generate_walk(0, 600.0)
    assert {t for _, _, t in walk.truth} == set(TERRAINS)
    lengths = [b - a for a, b, _ in walk.truth[:-1]]
    assert min(lengths) >= 5.0 and max(lengths) > 2 * min(lengths)
    assert all(x[2] != y[2] for x, y in zip(walk.truth, walk.truth[1:], strict=False))


def test_physics_is_plausible() -> None:
    walk = generate_walk(1, 120.0, conditions=RunConditions())  # the nominal robot: no gain, no mounting angle
    assert abs(walk.accel[:, 2].mean() - 9.81) < 0.2  # on average the feet carry the body
    np.testing.assert_allclose(np.linalg.norm(walk.quat, axis=1), 1.0, atol=1e-9)
    stance = walk.forces[:, :, 2] > 20.0
    assert 0.3 < stance.mean() < 0.8  # a trot: each foot on the ground about half the time


def test_terrains_differ_but_overlap() -> None:
    """A windowed feature separates terrains only partly: a sequence model has work to do."""
    walk = generate_walk(2, 900.0)
    per_terrain: dict[str, list[float]] = {}
    for a, b, t in walk.truth:
        seg = walk.accel[int(a * IMU_HZ) + 50 : int(b * IMU_HZ) - 50, 2]
        for i in range(0, len(seg) - 200, 200):
            per_terrain.setdefault(t, []).append(float(np.abs(np.diff(seg[i : i + 200])).mean()))
    means = {t: np.mean(v) for t, v in per_terrain.items()}
    assert max(means.values()) > 1.5 * min(means.values())  # learnable differences
    lo, hi = min(means, key=means.get), max(means, key=means.get)
    spread = {t: (np.percentile(v, 5), np.percentile(v, 95)) for t, v in per_terrain.items()}
    overlapping = sum(
        spread[x][1] > spread[y][0] and spread[y][1] > spread[x][0] for x in means for y in means if x < y
    )
    assert overlapping >= 5, "terrains must overlap on any single feature"
    assert spread[lo][1] < spread[hi][1]


def test_written_logs_have_two_rates_and_a_truth_sidecar(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    (path,) = generate_demo_logs(tmp_path, n_logs=1, minutes=0.5, seed=4)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: summary.statistics.channel_message_counts[i] for i, c in summary.channels.items()}
    feet = {"/feet/fl", "/feet/fr", "/feet/rl", "/feet/rr"}
    assert set(topics) == {"/imu", *feet, "/camera/ground/compressed", "/odom", "/gnss/fix"}
    assert abs(topics["/imu"] / topics["/feet/fl"] - IMU_HZ / FOOT_HZ) < 0.01
    assert abs(topics["/camera/ground/compressed"] / topics["/imu"] - CAMERA_FPS / IMU_HZ) < 0.002
    truth = json.loads(path.with_name("walk_000.truth.json").read_text())
    assert truth["log"] == "walk_000.mcap" and truth["segments"][0]["terrain"] in TERRAINS


def test_the_demo_camera_shows_the_terrain_under_the_feet() -> None:
    """Mid-patch, a frame's middle rows look like the patch's terrain: closest in mean colour to its texture."""
    import io

    from PIL import Image

    walk = generate_walk(11, 90.0)
    stamps, frames = ground_frames(walk, seed=11)
    colours = {k: terrain_tile(k, 11).reshape(-1, 3).mean(axis=0) for k in TERRAINS}
    checked = 0
    for a, b, terrain in walk.truth:
        if b - a < 4.0:
            continue
        i = int(np.argmin(np.abs(stamps - walk.t0 - (a + b) / 2)))
        rows = np.asarray(Image.open(io.BytesIO(frames[i])).convert("RGB"), np.float64)[HEIGHT // 3 : 2 * HEIGHT // 3]
        mean = rows.reshape(-1, 3).mean(axis=0)
        assert min(colours, key=lambda k: np.linalg.norm(colours[k] - mean)) == terrain
        checked += 1
    assert checked >= 3


def test_a_demo_walk_is_on_the_patch_of_the_terrain_under_it_at_every_moment() -> None:
    """The field's patches are the terrains (a sector each, meeting at the centre): the robot is in the sector of
    the terrain its truth names, wherever it is away from the centre, and its path is as long as the ground it
    covered (the camera's ground moves with ``Walk.distance``)."""
    from workbench.demo import TERRAINS, generate_walk
    from workbench.demo.field_path import field_positions

    walk = generate_walk(seed=4, duration_s=120.0)
    xy = field_positions(walk)  # (T, 2)
    sector = (np.floor(np.mod(np.arctan2(xy[:, 1], xy[:, 0]), 2 * np.pi) / (2 * np.pi / len(TERRAINS)))).astype(int)
    truth = np.empty(len(walk.times), object)
    for a, b, terrain in walk.truth:
        truth[(walk.times >= a) & (walk.times < b)] = terrain
    away = np.hypot(xy[:, 0], xy[:, 1]) > 0.5
    assert away.mean() > 0.8
    assert (np.asarray(TERRAINS, object)[sector[away]] == truth[away]).all()
    walked = np.hypot(*np.diff(xy, axis=0).T).sum()
    assert abs(walked - walk.distance[-1]) < 0.05 * walk.distance[-1]
