"""The page's map: paths of a shared frame drawn together, colours as the page's lines need them, a click's ground
point and the pose nearest it, and the view itself on a recording scene (the browser test clicks the real one)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from sessions import Session
from workbench.maps import LABEL, MODEL
from workbench.ui import MapView, ground_point, map_bounds, map_paths, nearest_pose, segment_colours

NO_SCORES = SimpleNamespace(scores={}, classes=())


def _run(path: Path, *, east_m: float, gnss: bool = True, seconds: float = 60.0, rate: float = 50.0) -> None:
    """North at 1 m/s, ``east_m`` east of the field's corner: as GNSS, or as a CSV's own ``x, y`` frame."""
    rng = np.random.default_rng(len(path.name))
    t = np.arange(int(seconds * rate)) / rate
    frame = pd.DataFrame({"time": t, "az": rng.normal(size=len(t))})
    if gnss:
        frame["lat"], frame["lon"] = 45.38 + t / 111_195.0, -71.92 + east_m / 78_200.0
    else:
        frame["x"], frame["y"] = east_m + 0.1 * t, t  # a little east as it goes: x moves like a position too
    frame.to_csv(path, index=False)


def _session(tmp_path: Path) -> Session:
    s = Session.create(tmp_path / "s")
    s.add_terrain("grass")
    for name, east, gnss in (("a", 0.0, True), ("b", 20.0, True), ("c", 5.0, False)):
        _run(tmp_path / f"{name}.csv", east_m=east, gnss=gnss)
    s.ingest([tmp_path / f"{n}.csv" for n in "abc"])
    s.add_segment(log_id=s.logs()[0].id, start=0, stop=1500, terrain="grass", author="me")  # a's first 30 s
    return s


def test_a_gnss_run_is_drawn_with_the_other_runs_of_its_frame_and_an_own_frame_alone(tmp_path: Path) -> None:
    s = _session(tmp_path)
    a, b, c = s.logs()
    mine, others = map_paths(s, NO_SCORES, a, s.segments(a.id))
    assert mine is not None and mine.frame == "wgs84" and [p.log for p in others] == [b.name]
    assert np.allclose(others[0].xy[0], (20.0, 0.0), atol=0.05)  # lined up: b is 20 m east of a
    lo, hi = map_bounds(mine, others)
    assert np.allclose(lo, (0.0, 0.0), atol=0.05) and np.allclose(hi, (20.0, 59.98), atol=0.05)
    own, alone = map_paths(s, NO_SCORES, c, s.segments(c.id))
    assert own is not None and own.frame != "wgs84" and alone == []  # a CSV's frame restarts with each run
    s.close()


def test_colours_are_the_terrains_darkened_for_the_pages_lines_and_labels_stronger_than_answers(tmp_path) -> None:
    s = _session(tmp_path)
    a = s.logs()[0]
    mine, _ = map_paths(s, NO_SCORES, a, s.segments(a.id))
    colours = segment_colours(mine, [("grass", "#4caf50")])
    assert colours.shape == (len(mine.times) - 1, 2, 3) and colours.dtype == np.uint8
    labelled = colours[mine.source[:-1] == LABEL][0, 0]
    # #4caf50 sent as linear light: the screen's sRGB brightens it back to the terrain's colour
    assert np.allclose(255 * (labelled / 255) ** (1 / 2.2), (0x4C, 0xAF, 0x50), atol=1.5)
    mine.source[:] = MODEL
    mine.terrain[:] = 0
    answer = segment_colours(mine, [("grass", "#4caf50")])[0, 0]
    assert (answer > labelled).all()  # lighter, the same hue
    s.close()


def test_a_clicks_ray_meets_the_ground_and_picks_the_nearest_pose() -> None:
    assert np.allclose(ground_point((1.0, 2.0, 10.0), (0.0, 0.6, -0.8)), (1.0, 9.5))
    assert ground_point((1.0, 2.0, 10.0), (1.0, 0.0, 0.0)) == (1.0, 2.0)  # parallel to the ground: below it
    xy = np.asarray([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    assert nearest_pose(xy, (4.0, 4.5)) == 2 and nearest_pose(xy, (0.6, 0.1)) == 1


class _Node(SimpleNamespace):
    def remove(self) -> None:
        self.removed = True


class _Scene:
    """Records what the view draws; hands back the click callback it registers."""

    def __init__(self) -> None:
        self.added: dict[str, _Node] = {}
        self.click = None

    def on_click(self):
        def register(fn):
            self.click = fn
            return fn

        return register

    def _add(self, name: str, *args, **kwargs) -> _Node:
        node = _Node(name=name, visible=True, position=kwargs.get("position"), args=args, kwargs=kwargs)
        self.added[name] = node
        return node

    add_line_segments = add_label = add_icosphere = _add


def test_the_view_draws_the_path_moves_its_marker_and_turns_a_click_into_the_cursor(tmp_path: Path) -> None:
    s = _session(tmp_path)
    a = s.logs()[0]
    scene, moved = _Scene(), []
    camera = SimpleNamespace(position=(3.0, 3.0, 3.0), look_at=(0.0, 0.0, 0.0))
    host = SimpleNamespace(
        client=SimpleNamespace(scene=scene, camera=camera),
        state=SimpleNamespace(session=s, scores=NO_SCORES),
        log=a,
        cursor_s=0.0,
        guard=lambda fn: fn(),
        move_cursor=moved.append,
    )
    robot = _Node(visible=True)
    view = MapView(host, robot_nodes=[robot])
    assert view.has_positions(a) and view.toggle() is True and robot.visible is False
    assert {"/map/path1", "/map/label1", "/map/other0", "/map/marker"} <= set(scene.added)  # b under a, a's labels
    assert scene.added["/map/path1"].kwargs["thickness_units"] == "screen"
    assert np.allclose(scene.added["/map/marker"].position, (-10.0, -29.99, 0.0), atol=0.05)  # a's start, centred
    host.cursor_s = 30.0
    view.update()
    assert np.allclose(scene.added["/map/marker"].position, (-10.0, 0.0, 0.0), atol=0.05)
    scene.click(SimpleNamespace(ray_origin=(-10.0, 20.0, 50.0), ray_direction=(0.0, 0.0, -1.0)))
    assert len(moved) == 1 and abs(moved[0] - 50.0) < 0.2  # 20 m north of the centre: 50 s into a
    assert view.toggle() is False and robot.visible is True
    assert camera.position == (3.0, 3.0, 3.0) and camera.look_at == (0.0, 0.0, 0.0)  # the robot's view given back
    scene.click(SimpleNamespace(ray_origin=(0.0, 0.0, 50.0), ray_direction=(0.0, 0.0, -1.0)))
    assert len(moved) == 1  # the robot's view: a click is the camera's, not the cursor's
    s.close()
