"""The camera: the frame at the cursor, above the side panel, for logs that recorded one.

Terrain is judged by looking at the ground: the picture follows the cursor (arrow keys, a suggestion's jump, Space
playing the log back). Frames go to the page as the JPEG bytes the session keeps, in an ``<img>``: nothing is decoded
or encoded again on the server.
"""

from __future__ import annotations

import base64
import html
from typing import TYPE_CHECKING

from sessions import CameraInfo

from ..user_errors import USER_ERRORS, one_line

if TYPE_CHECKING:
    from .host import PanelHost

WITHIN_S = 1.0  # no frame this close to the cursor: say so rather than show an older picture


class CameraPanel:
    """A movable panel docked above the side panel; hidden while the log on screen has no camera."""

    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        self.panel = gui.add_panel(visible=False)
        with self.panel.add_tab("Camera", icon="camera"):
            self.picture = gui.add_html("")
            self.pick = gui.add_dropdown("Camera", ("(none)",), visible=False, hint="Which image topic to show")
        self.pick.on_update(lambda _: host.guard(self._picked))
        self.panel.dock_above(gui.main_panel)
        self._cameras: tuple[int, list[CameraInfo]] | None = None  # (log id, its cameras)
        self._camera = 0
        self._shown: tuple | None = None

    def _picked(self) -> None:
        names = [c.topic for c in self._cameras[1]] if self._cameras else []
        if self.pick.value in names:
            self._camera = names.index(self.pick.value)
            self._shown = None
            self.update()

    def update(self) -> None:
        """Show the frame at the cursor of the log on screen (sent only when it changed)."""
        log = self.host.log
        session = self.host.state.session
        if log is None:
            self.panel.visible = False
            return
        try:
            if self._cameras is None or self._cameras[0] != log.id:
                self._cameras = (log.id, session.cameras(log.id))
                self._camera = 0
                self._shown = None
                cams = self._cameras[1]
                with self.host.quiet():
                    self.pick.options = tuple(c.topic for c in cams) or ("(none)",)
                    self.pick.visible = len(cams) > 1
            cams = self._cameras[1]
            self.panel.visible = bool(cams)
            if not cams:
                return
            number = session.camera_frame_number(log.id, self.host.cursor_s, camera=self._camera, within_s=WITHIN_S)
            key = (log.id, self._camera, number)
            if key == self._shown:  # redraws come with every cursor step: read a frame only when it changes
                return
            frame = (
                None
                if number is None
                else session.camera_frame(log.id, self.host.cursor_s, camera=self._camera, within_s=WITHIN_S)
            )
        except USER_ERRORS as exc:  # damaged camera files: one line where the picture would be
            self.panel.visible = True
            self.picture.content = f"<p style='color:#c62828;font-size:0.8em'>{html.escape(one_line(exc))}</p>"
            self._shown = None
            return
        cam = cams[self._camera]
        self._shown = key
        topic = html.escape(cam.topic)
        if frame is None:
            self.picture.content = (
                f"<div style='font-size:0.8em;color:#666;padding:2em 0;text-align:center'>{topic}: no frame within "
                f"{WITHIN_S:g} s of the cursor</div>"
            )
            return
        data = base64.b64encode(frame.jpeg).decode("ascii")
        self.picture.content = (
            f"<img data-frame='{frame.number}' src='data:image/jpeg;base64,{data}' "
            f"style='width:100%;display:block;border-radius:4px' alt='camera frame'>"
            f"<div style='font-size:0.75em;color:#555'>{topic} · frame {frame.number + 1} of {frame.of} at "
            f"{max(frame.t, 0.0):.1f} s</div>"
        )
