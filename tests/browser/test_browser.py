"""simbot's live view in a real browser: headless Chromium (Debian's) driven by Playwright opens
Foxglove Studio 1.48 (the web bundle of `@foxglove/studio-base` from npm, served from localhost by
the test) on a live `simbot foxglove`, with simbot's layout, and checks what a person would.

`make test-browser` runs it (installing Chromium with apt and Playwright with pip first); `make
test` does not collect this folder. Without Chromium, npm or Playwright it skips, saying which.

The world is tests/fixtures/scene_room.sdf with the tug at the server's default spawn point,
standing still, and the merger, the stitcher and the bridge running. Checked on the screenshot:
- the scan panel (top-down, 14 m tall, centred on the robot) draws the scene: the north wall's
  yellow along its projected line, the ball's white and the crate's orange at theirs, the floor
  between them bare; and the scan: its red where the front lidar meets the north wall's face
  (seen from above, returns on surfaces taller than the lidar's plane show only at their edges);
- the image panel shows the panorama with the front camera's picture in its middle: the east
  wall's green ahead, and the north wall's yellow seen by the left cameras.
The screenshot is kept in build/browser/ (a copy is docs/foxglove-studio.png in the README).
"""

from __future__ import annotations

import functools
import http.server
import shutil
import subprocess
import tarfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from bus_helpers import free_port
from client_helpers import client_process
from conftest import REPO
from server_helpers import running_server, wait_until

pytestmark = pytest.mark.browser

CHROMIUM = shutil.which("chromium")
NPM = shutil.which("npm")
STUDIO = "@foxglove/studio-base@1.48.0"
REACT = ("react@17.0.2", "react-dom@17.0.2")
CACHE = Path.home() / ".cache" / "simbot" / "studio-base-1.48.0"
HERE = Path(__file__).resolve().parent
ARTIFACTS = REPO / "build" / "browser"
WORLD = REPO / "tests" / "fixtures" / "scene_room.sdf"
ROBOT_AT = (-2.5, 0.0)
"""The server's default spawn point, where the robot stands (it is never driven here)."""
VIEW_M = 14.0
"""The scan panel's view: top-down, orthographic, this many metres from the canvas's top to its bottom."""
DEADLINE_S = 600.0
"""Two cores shared with other test runs: the page loads, connects and draws in minutes, not seconds."""
SHOT_EVERY_S = 5.0
"""Seconds between screenshots while the page loads and draws (each costs a second of a loaded core)."""
CHROMIUM_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
"""WebGL on the CPU (SwiftShader): the 3D panels need it and the test machine has no GPU."""


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
    """This folder's page, the npm packages and simbot's layout, served on a free loopback port."""
    _skip_without_tools()
    _npm_packages(CACHE)
    root = tmp_path_factory.mktemp("site")
    for name in ("studio", "react", "react-dom"):
        (root / name).symlink_to(CACHE / name)
    shutil.copy(HERE / "studio.html", root / "studio.html")
    shutil.copy(REPO / "layouts" / "simbot.json", root / "layout.json")
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


def _canvases(page: Any) -> dict[str, tuple[int, int, int, int]]:
    """The canvases of the panels by the panel's place: `image` top left, `scan` below it, `frames` right."""
    boxes = [page.locator("canvas").nth(i).bounding_box() for i in range(page.locator("canvas").count())]
    boxes = [b for b in boxes if b and b["width"] > 100 and b["height"] > 100]
    assert len(boxes) >= 3, f"expected the layout's three panels, found canvases {boxes}"
    left = sorted((b for b in boxes if b["x"] < min(c["x"] for c in boxes) + 10), key=lambda b: b["y"])
    right = max(boxes, key=lambda b: b["x"])
    return {
        name: (round(b["x"]), round(b["y"]), round(b["width"]), round(b["height"]))
        for name, b in (("image", left[0]), ("scan", left[-1]), ("frames", right))
    }


def _screen(box: tuple[int, int, int, int], xy: tuple[float, float]) -> tuple[float, float]:
    """Where the scan panel draws world point `xy` (top-down, VIEW_M tall, centred on the robot, x to the right)."""
    x0, y0, width, height = box
    scale = height / VIEW_M
    return x0 + width / 2 + (xy[0] - ROBOT_AT[0]) * scale, y0 + height / 2 - (xy[1] - ROBOT_AT[1]) * scale


def _pixel(shot: np.ndarray, box: tuple[int, int, int, int], xy: tuple[float, float]) -> np.ndarray:
    """The mean RGB around the screen point where the scan panel draws world point `xy`."""
    px, py = _screen(box, xy)
    patch = shot[round(py) - 1 : round(py) + 2, round(px) - 1 : round(px) + 2]
    return patch.reshape(-1, 3).mean(axis=0)


def _yellow(rgb: np.ndarray) -> bool:
    return bool(rgb[0] > 60 and rgb[1] > 0.7 * rgb[0] and rgb[2] < 0.4 * rgb[1])


def _green(rgb: np.ndarray) -> bool:
    return bool(rgb[1] > 60 and rgb[1] > 1.5 * rgb[0] and rgb[1] > 1.5 * rgb[2])


def _orange(rgb: np.ndarray) -> bool:
    return bool(rgb[0] > 150 and 0.3 * rgb[0] < rgb[1] < 0.85 * rgb[0] and rgb[2] < 0.4 * rgb[0])


def _white(rgb: np.ndarray) -> bool:
    return bool(rgb.min() > 170)


SCENE_POINTS = {
    "the north wall (yellow)": ([(x, 5.0) for x in (-4.0, -2.0, 0.0, 2.0)], _yellow),
    "the ball (white)": ([(-3.0, 3.0)], _white),
    "the crate (orange)": ([(2.0, 2.0)], _orange),
}
BARE_FLOOR = [(0.0, -2.0), (-1.0, 3.5)]


def _red(rgb: np.ndarray) -> bool:
    return bool(rgb[0] > 180 and rgb[1] < 0.5 * rgb[0] and rgb[2] < 0.5 * rgb[0])


WALL_FACE_Y = 4.9
"""The north wall's south face, which the front lidar (160 deg wide, 0.99 m ahead of the robot) sees from x = -0.6 on."""


def _scan_drawn(shot: np.ndarray, box: tuple[int, int, int, int]) -> list[str]:
    """Red returns along the north wall's face, between x 0 and 3 m: pixels in a band from 15 cm short of
    the face to 5 cm into the wall (the returns' points are half hidden by the wall's top)."""
    (left, top), (right, bottom) = _screen(box, (0.0, WALL_FACE_Y + 0.05)), _screen(box, (3.0, WALL_FACE_Y - 0.15))
    band = shot[round(top) : round(bottom) + 1, round(left) : round(right) + 1].reshape(-1, 3)
    hits = sum(map(_red, band))
    return [] if hits >= 20 else [f"the scan along the north wall's face ({hits} red pixels of {len(band)})"]


def _scene_drawn(shot: np.ndarray, box: tuple[int, int, int, int]) -> list[str]:
    """What is missing from the scan panel: each scene object's colour at its projected place, bare floor elsewhere."""
    missing = [
        f"{name} at {xy}: {_pixel(shot, box, xy).round()}"
        for name, (points, colour) in SCENE_POINTS.items()
        for xy in points
        if not colour(_pixel(shot, box, xy))
    ]
    for xy in BARE_FLOOR:
        rgb = _pixel(shot, box, xy)
        if any(colour(rgb) for _, colour in SCENE_POINTS.values()):
            missing.append(f"bare floor at {xy}: {rgb.round()}")
    return missing


def _camera_shown(shot: np.ndarray, box: tuple[int, int, int, int]) -> list[str]:
    """What is missing from the panorama: the east wall's green in its middle (the front camera), yellow anywhere."""
    x0, y0, width, height = box
    image = shot[y0 : y0 + height, x0 : x0 + width].reshape(-1, 3)
    middle = shot[y0 : y0 + height, x0 + width // 3 : x0 + 2 * width // 3].reshape(-1, 3)
    missing = []
    if sum(map(_green, middle[::7])) < 20:
        missing.append("the east wall's green in the middle of the panorama (the front camera)")
    if sum(map(_yellow, image[::7])) < 20:
        missing.append("the north wall's yellow in the panorama")
    return missing


def _screenshot(page: Any, path: Path) -> np.ndarray:
    path.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(path), timeout=DEADLINE_S * 1000)
    shot = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return cv2.cvtColor(shot, cv2.COLOR_BGR2RGB)


def test_foxglove_studio_shows_the_scene_and_the_camera(site: str) -> None:
    playwright = _skip_without_tools()
    port = free_port()
    with (
        running_server(str(WORLD), "realtime", extra=("--camera-size", "160x120")) as sim,
        client_process(sim, "merger"),
        client_process(sim, "stitcher"),
        client_process(sim, "foxglove", "--port", str(port)),
        playwright.sync_playwright() as driver,
    ):
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            url = f"{site}?ds=foxglove-websocket&ds.url=ws://127.0.0.1:{port}&layoutId=simbot"
            page.goto(url, timeout=DEADLINE_S * 1000)
            missing = ["the page"]

            def on_screen() -> bool:
                shot = _screenshot(page, ARTIFACTS / "simbot-foxglove.png")
                boxes = _canvases(page)
                missing[:] = [
                    *_scene_drawn(shot, boxes["scan"]),
                    *_scan_drawn(shot, boxes["scan"]),
                    *_camera_shown(shot, boxes["image"]),
                ]
                return not missing

            try:
                wait_until(on_screen, DEADLINE_S, "simbot's layout on the screen", poll=SHOT_EVERY_S)
            except AssertionError as late:
                raise AssertionError(f"{late}: {missing}; page errors {page.evaluate('window.studioErrors')}") from None
        finally:
            browser.close()
