"""simbot's live view in a real browser: headless Chromium (Debian's) driven by Playwright opens
Foxglove Studio 1.48 (the web bundle of `@foxglove/studio-base` from npm, served from localhost by
the test) on a live `simbot foxglove`, with simbot's layout, and checks what a person would.

`make test-browser` runs it (installing Chromium with apt and Playwright with pip first); `make
test` does not collect this folder. Without Chromium, npm or Playwright it skips, saying which.

Two runs, each with the merger, the stitcher and the bridge beside a real-time server:

- the test room, tests/fixtures/scene_room.sdf, the tug standing still at the server's default
  spawn point. Checked on the screenshot, at the places where the 3D panel's camera (read from the
  layout: behind and above base_link) projects them: the scene's north wall yellow, the ball
  white and the crate orange, the floor between them bare; the scan's red along the north wall's
  face, at the foot of the wall (the merged scan lies in base_link's plane); the front camera's
  panel shows the east wall's green in its middle, and so does the panorama, with the north
  wall's yellow seen by the left cameras.
- `make run`'s warehouse (`--add warehouse_people`): the README's picture. Taken once the
  meshes the scene names (the tug's, the people's) are loaded, the tug's orange is drawn where
  base_link projects, the scan is drawn, both image panels show a picture, and no tooltip is on
  screen. It is kept as build/browser/simbot-warehouse.png; docs/foxglove-studio.png, the
  README's picture, is a copy of it.
"""

from __future__ import annotations

import functools
import http.server
import json
import math
import shutil
import subprocess
import tarfile
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from bus_helpers import free_port
from client_helpers import ClientProcess, client_process
from conftest import REPO
from server_helpers import SimServer, running_server, wait_until

pytestmark = pytest.mark.browser

CHROMIUM = shutil.which("chromium")
NPM = shutil.which("npm")
STUDIO = "@foxglove/studio-base@1.48.0"
REACT = ("react@17.0.2", "react-dom@17.0.2")
CACHE = Path.home() / ".cache" / "simbot" / "studio-base-1.48.0"
HERE = Path(__file__).resolve().parent
ARTIFACTS = REPO / "build" / "browser"
LAYOUT = REPO / "layouts" / "simbot.json"
ROOM = REPO / "tests" / "fixtures" / "scene_room.sdf"
MESH_FOLDERS = ("meshes", "worlds")
"""Where the scenes' mesh files are: the page fetches them from the test's server (see studio.html)."""
ODOM_AT = np.array([-2.5, 0.0, 0.19])
"""odom's origin in the world: base_link where the robot entered, at the server's default spawn point
(0.1 m up) plus base_link's 0.09 m over base_footprint. The robot is never driven here, so base_link
stays there, heading along x."""
DEADLINE_S = 600.0
"""Two cores shared with other test runs: the page loads, connects and draws in minutes, not seconds."""
SHOT_EVERY_S = 5.0
"""Seconds between screenshots while the page loads and draws (each costs a second of a loaded core)."""
BRIDGE_LOG_CHARS = 3000
"""How much of the bridge's log a failure shows: its channels and viewers, what it forwarded."""
VIEWPORT = {"width": 1600, "height": 900}
CHROMIUM_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
"""WebGL on the CPU (SwiftShader): the 3D panel needs it and the test machine has no GPU."""
Box = tuple[int, int, int, int]
"""A canvas on the screen: x, y, width, height in CSS pixels."""
Colour = Callable[[np.ndarray], bool]
"""Whether an RGB triple is of one colour."""
Point = tuple[float, float, float]
"""A point of the world, in metres."""


def _skip_without_tools() -> Any:
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed (apt-get install -y chromium): no browser test")
    if NPM is None:
        pytest.skip("npm is not installed: Foxglove Studio's bundle comes from npm")
    return pytest.importorskip("playwright.sync_api", reason="Playwright is not installed (pip install playwright)")


def _npm_packages(folder: Path) -> None:
    """studio-base's bundle and React 17 as npm packs them (no install scripts, no dependencies), unpacked."""
    if (folder / "studio" / "assets" / "index.js").exists():
        return
    assert NPM is not None, "npm is not installed (_skip_without_tools skips first)"
    folder.mkdir(parents=True, exist_ok=True)
    for spec in (STUDIO, *REACT):
        done = subprocess.run(
            [NPM, "pack", spec, "--silent", "--pack-destination", str(folder)],
            capture_output=True,
            text=True,
            timeout=600,
            check=False,
        )
        assert done.returncode == 0, f"npm pack {spec}:\n{done.stderr}"
        archive = folder / done.stdout.strip().splitlines()[-1]
        target = folder / ("studio" if spec == STUDIO else spec.rsplit("@", 1)[0])
        with tarfile.open(archive) as packed:
            packed.extractall(folder / "unpack", filter="data")
        shutil.rmtree(target, ignore_errors=True)
        (folder / "unpack" / "package").rename(target)
        archive.unlink()


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """This folder's page, the npm packages, simbot's layout and the mesh folders, served on a free loopback port.

    The mesh folders are under `files/` at their absolute paths, where the page looks for a `file://`
    URI the scene names."""
    _skip_without_tools()
    _npm_packages(CACHE)
    root = tmp_path_factory.mktemp("site")
    for name in ("studio", "react", "react-dom"):
        (root / name).symlink_to(CACHE / name)
    files = root / "files" / REPO.relative_to(REPO.anchor)
    files.mkdir(parents=True)
    for name in MESH_FOLDERS:
        (files / name).symlink_to(REPO / name)
    shutil.copy(HERE / "studio.html", root / "studio.html")
    shutil.copy(LAYOUT, root / "layout.json")
    handler = functools.partial(_QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_port}/studio.html"
    finally:
        server.shutdown()
        thread.join()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *_args: Any) -> None:
        """Requests are not worth a line each in the test's output."""


@dataclass
class Studio:
    """The page, the URLs of the files it has fetched so far, the bridge it shows and the server behind."""

    page: Any
    fetched: list[str]
    bridge: ClientProcess
    server: SimServer

    def saw(self, response: Any) -> None:
        """Playwright's response handler: a file fetched, or not."""
        if response.ok:
            self.fetched.append(response.url)


@contextmanager
def _studio(site: str, world: str, *server_args: str) -> Iterator[Studio]:
    """Studio in headless Chromium on `simbot foxglove`, beside the merger and the stitcher, on a real-time server."""
    playwright = _skip_without_tools()
    port = free_port()
    with (
        running_server(world, "realtime", extra=server_args) as sim,
        client_process(sim, "merger"),
        client_process(sim, "stitcher"),
        client_process(sim, "foxglove", "--port", str(port)) as bridge,
        playwright.sync_playwright() as driver,
    ):
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport=VIEWPORT)
            studio = Studio(page, [], bridge, sim)
            page.on("response", studio.saw)
            url = f"{site}?ds=foxglove-websocket&ds.url=ws://127.0.0.1:{port}&layoutId=simbot"
            page.goto(url, timeout=DEADLINE_S * 1000)
            yield studio
        finally:
            browser.close()


CANVAS_BOXES = """[...document.querySelectorAll("canvas")].map((canvas) => {
  const box = canvas.getBoundingClientRect();
  return [box.x, box.y, box.width, box.height];
})"""
"""Every canvas's box, in one call (a locator per canvas waits for each, which a loaded page can make time out)."""


def _canvases(page: Any) -> dict[str, Box]:
    """The panels' canvases: `tug` (the 3D panel, the largest), `front` and `panorama` (right of it, top to
    bottom); empty until all three are on the page."""
    boxes = [(round(x), round(y), round(w), round(h)) for x, y, w, h in page.evaluate(CANVAS_BOXES)]
    boxes = [box for box in boxes if box[2] > 100 and box[3] > 100]
    if len(boxes) < 3:
        return {}
    tug = max(boxes, key=lambda box: box[2] * box[3])
    images = sorted((box for box in boxes if box[0] >= tug[0] + tug[2] - 10), key=lambda box: box[1])
    return {"tug": tug, "front": images[0], "panorama": images[-1]} if len(images) >= 2 else {}


def _about_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _about_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _tug_panel(content: dict[str, Any]) -> dict[str, Any]:
    """The layout's 3D panel, through its split containers."""
    if content["type"] == "panel":
        return content if content["panelType"] == "ThreeDee" else {}
    return next(filter(None, (_tug_panel(item["content"]) for item in content["items"])), {})


@dataclass(frozen=True)
class View:
    """The 3D panel's perspective camera as Studio places it (Renderer._updateCameras: a three.js
    camera at spherical coordinates round the target, turned by Euler(phi, 0, -thetaOffset, "ZYX")),
    in base_link's frame, which is odom's here; and the canvas it draws on."""

    box: Box
    eye: np.ndarray
    turn: np.ndarray
    """Columns: the camera's right, up and backward directions."""
    focal_px: float

    @classmethod
    def of_layout(cls, box: Box) -> View:
        state = _tug_panel(json.loads(LAYOUT.read_text())["content"])["config"]["cameraState"]
        assert state["perspective"], "the 3D panel's camera is not a perspective one"
        turn = _about_z(-math.radians(state["thetaOffset"])) @ _about_x(math.radians(state["phi"]))
        eye = np.array(state.get("targetOffset", (0.0, 0.0, 0.0))) + state["distance"] * turn[:, 2]
        return cls(box, eye, turn, box[3] / 2 / math.tan(math.radians(state["fovy"]) / 2))

    def screen(self, world: Point) -> tuple[float, float]:
        """Where the panel draws a point of the world."""
        right, up, back = (np.asarray(world) - ODOM_AT - self.eye) @ self.turn
        x0, y0, width, height = self.box
        return x0 + width / 2 + self.focal_px * right / -back, y0 + height / 2 - self.focal_px * up / -back

    def patch(self, shot: np.ndarray, world: Point, radius: int) -> np.ndarray | None:
        """The RGB pixels within `radius` of where the panel draws `world`; None where that is off the canvas."""
        px, py = (round(v) for v in self.screen(world))
        x0, y0, width, height = self.box
        if not (x0 + radius <= px < x0 + width - radius and y0 + radius <= py < y0 + height - radius):
            return None
        return shot[py - radius : py + radius + 1, px - radius : px + radius + 1].reshape(-1, 3)

    def colour(self, shot: np.ndarray, world: Point) -> np.ndarray | None:
        """The mean RGB of the 3×3 pixels where the panel draws `world`; None off the canvas."""
        patch = self.patch(shot, world, 1)
        return None if patch is None else patch.mean(axis=0)

    def count(self, shot: np.ndarray, world: Point, radius: int, colour: Colour) -> int:
        """How many pixels within `radius` of where the panel draws `world` are of `colour` (none off the canvas)."""
        patch = self.patch(shot, world, radius)
        return 0 if patch is None else sum(map(colour, patch))


def _yellow(rgb: np.ndarray) -> bool:
    return bool(rgb[0] > 60 and rgb[1] > 0.7 * rgb[0] and rgb[2] < 0.4 * rgb[1])


def _green(rgb: np.ndarray) -> bool:
    return bool(rgb[1] > 60 and rgb[1] > 1.5 * rgb[0] and rgb[1] > 1.5 * rgb[2])


def _orange(rgb: np.ndarray) -> bool:
    return bool(rgb[0] > 150 and 0.3 * rgb[0] < rgb[1] < 0.85 * rgb[0] and rgb[2] < 0.4 * rgb[0])


def _white(rgb: np.ndarray) -> bool:
    return bool(rgb.min() > 170)


def _red(rgb: np.ndarray) -> bool:
    """The scan's flat #ff3b30, and not the tug's orange (225, 92, 33 lit) nor the trolley's dark red legs."""
    return bool(rgb[0] > 220 and rgb[1] < 0.3 * rgb[0] and rgb[2] < 0.3 * rgb[0])


SCENE_POINTS: dict[str, tuple[list[Point], Colour]] = {
    "the north wall's face (yellow)": ([(x, 4.9, 1.0) for x in (1.0, 2.5, 4.0)], _yellow),
    "the ball (white)": ([(-3.0, 3.0, 0.4)], _white),
    "the crate (orange)": ([(2.0, 2.0, 0.4)], _orange),
}
BARE_FLOOR = [(0.0, -2.0, 0.0), (-1.0, 3.5, 0.0)]
SCAN_ON_THE_WALL = [(0.5 + 0.25 * i, 4.85, float(ODOM_AT[2])) for i in range(15)]
"""The front lidar's returns on the north wall's face (it sees it from x = -0.6 on), where the merged scan
draws them: in base_link's plane, a little short of the face (the points are half hidden by the wall)."""


def _scene_drawn(shot: np.ndarray, view: View) -> list[str]:
    """What is missing from the 3D panel: each scene object's colour where it projects, bare floor elsewhere."""
    missing = []
    for name, (points, colour) in SCENE_POINTS.items():
        for xyz in points:
            rgb = view.colour(shot, xyz)
            if rgb is None or not colour(rgb):
                missing.append(f"{name} at {xyz}: {'off the canvas' if rgb is None else rgb.round()}")
    for xyz in BARE_FLOOR:
        rgb = view.colour(shot, xyz)
        if rgb is None or any(colour(rgb) for _, colour in SCENE_POINTS.values()):
            missing.append(f"bare floor at {xyz}: {'off the canvas' if rgb is None else rgb.round()}")
    return missing


def _scan_drawn(shot: np.ndarray, view: View) -> list[str]:
    """Red returns along the foot of the north wall's face."""
    hits = sum(view.count(shot, xyz, 4, _red) for xyz in SCAN_ON_THE_WALL)
    return [] if hits >= 20 else [f"the scan along the north wall's face ({hits} red pixels)"]


def _panel_pixels(shot: np.ndarray, box: Box, middle: bool = False) -> np.ndarray:
    """Every 7th RGB pixel of a panel's canvas (of its middle third across, with `middle`)."""
    x0, y0, width, height = box
    if middle:
        x0, width = x0 + width // 3, width // 3
    return shot[y0 : y0 + height, x0 : x0 + width].reshape(-1, 3)[::7]


def _cameras_shown(shot: np.ndarray, boxes: dict[str, Box]) -> list[str]:
    """What is missing from the image panels: the east wall's green in the middle of the front camera's
    picture and of the panorama (the front camera's part); the north wall's yellow in the panorama."""
    missing = []
    for name in ("front", "panorama"):
        if sum(map(_green, _panel_pixels(shot, boxes[name], middle=True))) < 20:
            missing.append(f"the east wall's green in the middle of the {name} panel")
    if sum(map(_yellow, _panel_pixels(shot, boxes["panorama"]))) < 20:
        missing.append("the north wall's yellow in the panorama")
    return missing


def _screenshot(page: Any, path: Path) -> np.ndarray:
    path.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(path), timeout=DEADLINE_S * 1000)
    shot = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert shot is not None, f"{path} is not an image"
    return cv2.cvtColor(shot, cv2.COLOR_BGR2RGB)


def _wait_for(studio: Studio, path: Path, missing_from: Callable[[np.ndarray, dict[str, Box]], list[str]]) -> None:
    """Screenshots into `path` until nothing is missing from one; AssertionError naming what is, after DEADLINE_S."""
    missing = ["the page"]

    def on_screen() -> bool:
        shot = _screenshot(studio.page, path)
        boxes = _canvases(studio.page)
        missing[:] = missing_from(shot, boxes) if boxes else ["the three panels' canvases"]
        return not missing

    try:
        wait_until(on_screen, DEADLINE_S, "simbot's layout on the screen", poll=SHOT_EVERY_S)
    except AssertionError as late:
        errors = studio.page.evaluate("window.studioErrors")
        log = studio.bridge.stderr()[-BRIDGE_LOG_CHARS:]
        raise AssertionError(
            f"{late}: {missing}; page errors {errors}; the server's errors {studio.server.errors()}; "
            f"the bridge's log ends:\n{log}"
        ) from None


def test_foxglove_studio_shows_the_scene_and_the_camera(site: str) -> None:
    def missing_from(shot: np.ndarray, boxes: dict[str, Box]) -> list[str]:
        view = View.of_layout(boxes["tug"])
        return [*_scene_drawn(shot, view), *_scan_drawn(shot, view), *_cameras_shown(shot, boxes)]

    with _studio(site, str(ROOM), "--camera-size", "160x120") as studio:
        _wait_for(studio, ARTIFACTS / "simbot-foxglove.png", missing_from)


WAREHOUSE_MESHES = ("chassis.stl", "worker.dae")
"""The tug's body and the people, as the scene names them."""
TUG = (-2.5, 0.0, 0.35)
"""The top of the tug's chassis, over base_link."""


def _warehouse_drawn(shot: np.ndarray, boxes: dict[str, Box], fetched: list[str]) -> list[str]:
    """What is missing from the README's picture: the meshes, the tug's orange round base_link, the scan's
    red in the 3D panel, a picture in each image panel."""
    missing = [f"the mesh {name}" for name in WAREHOUSE_MESHES if not any(url.endswith(name) for url in fetched)]
    view = View.of_layout(boxes["tug"])
    if view.count(shot, TUG, 30, _orange) < 100:
        missing.append("the tug's orange round base_link")
    if sum(map(_red, _panel_pixels(shot, boxes["tug"]))) < 20:
        missing.append("the scan's red in the 3D panel")
    for name in ("front", "panorama"):
        if _panel_pixels(shot, boxes[name], middle=True).std() < 20:
            missing.append(f"a picture in the {name} panel")
    return missing


def test_the_readmes_picture_of_the_warehouse(site: str) -> None:
    """`make run`'s world and clients in simbot's layout, with no tooltip over it: docs/foxglove-studio.png."""
    with _studio(site, "warehouse", "--add", "warehouse_people") as studio:

        def missing_from(shot: np.ndarray, boxes: dict[str, Box]) -> list[str]:
            tooltips = studio.page.get_by_role("tooltip").count()
            return _warehouse_drawn(shot, boxes, studio.fetched) + [f"no tooltip, not {tooltips}"] * bool(tooltips)

        _wait_for(studio, ARTIFACTS / "simbot-warehouse.png", missing_from)
