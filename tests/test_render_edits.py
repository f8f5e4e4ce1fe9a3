"""A running render pool edited in place (simbot/sim/render/pool.py `edit`, `update_camera`): bodies out, in
and replaced in one edit, the lighting changed, a camera's noise changed; an edited scene drawn exactly as a
pool started on it draws it; a worker that dies during an edit started again, its frame dropped; the textures'
mip chains kept on disk and uploaded as GL built them; workers forked from the fork server.
"""

from __future__ import annotations

import math
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from gl_helpers import NO_EGL, body_of, box_body, box_model
from server_helpers import wait_until

from simbot.sim.render import CameraSpec, Light, LightSource, RenderPool, SceneBody
from simbot.sim.render import textures as texture_cache
from simbot.transform import Transform

W, H = 160, 120
FX = 80.0
HFOV = 2.0 * math.atan((W / 2) / FX)
WAIT = 30.0
AHEAD: Transform = Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
RED, GREEN, BLUE, GREY = (1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0)
CAMERAS = [CameraSpec("rgb", W, H, HFOV, 0.05, 50.0), CameraSpec("noisy", W, H, HFOV, 0.05, 50.0, seed=3)]
RGB, NOISY = 0, 1
SUN = Light(sources=(LightSource(diffuse=(0.4, 0.4, 0.4), direction=(1.0, 0.0, -0.2), cast_shadows=True),))
DIM = Light(
    sources=(LightSource(diffuse=(0.2, 0.2, 0.2), direction=(1.0, 0.3, -0.5), cast_shadows=True),),
    ambient=(0.3, 0.3, 0.3),
)
TEXTURE = Path(__file__).resolve().parents[1] / "worlds" / "textures" / "floor_a.jpg"


def at(x: float, y: float, z: float = 0.0) -> Transform:
    return Transform((x, y, z), (0.0, 0.0, 0.0, 1.0))


def wall(name: str, rgba: tuple[float, float, float, float], y: float, static: bool = True) -> SceneBody:
    """A 0.6 m square 3 m ahead of the cameras, `y` m to their left."""
    return box_body(name, (0.1, 0.6, 0.6), rgba, static, at(3.05, y))


def backdrop() -> SceneBody:
    return box_body("backdrop", (0.1, 20.0, 20.0), GREY, True, at(6.05, 0.0))


@pytest.fixture(params=["gl", "tiny"])
def renderer(request: pytest.FixtureRequest) -> str:
    if request.param == "gl" and NO_EGL:
        pytest.skip(NO_EGL)
    return str(request.param)


def frame(pool: RenderPool, camera: int = RGB, stamp: int = 1) -> npt.NDArray[np.uint8]:
    pool.request(camera, stamp, AHEAD, {})
    (done,) = [f for f in pool.collect(wait_for=camera, timeout=WAIT) if f.camera == camera]
    return np.array(done["color"])


def started(bodies: list[SceneBody], light: Light, renderer: str, workers: int = 1) -> RenderPool:
    return RenderPool(bodies, CAMERAS, workers=workers, renderer=renderer, light=light)


def test_an_edited_scene_draws_as_a_pool_started_on_it(renderer: str) -> None:
    """Three walls and a backdrop, then one edit: two walls out (static and moving), one replaced by a wall of
    another colour at another place, a new one in, other lights. The picture equals, pixel for pixel, that of a
    pool started on the edited scene, and no wall that left is drawn."""
    before = [wall("a", RED, 1.0), wall("b", GREEN, 0.0), wall("c", BLUE, -1.0, static=False), backdrop()]
    after = [wall("a", BLUE, 0.5), backdrop(), wall("d", GREEN, -0.5)]
    with started(before, SUN, renderer) as pool:
        frame(pool)
        pool.edit(removed=("a", "b", "c"), added=(after[0], after[2]), light=DIM, order=[b.name for b in after])
        edited = frame(pool)
        assert pool.body_names == {"a", "backdrop", "d"}
    with started(after, DIM, renderer) as fresh:
        expected = frame(fresh)
    differing = int((edited != expected).any(axis=2).sum())
    assert differing == 0, f"{differing} pixels differ from a pool started on the edited scene"
    red = (edited[:, :, 0] > 150) & (edited[:, :, 1] < 60) & (edited[:, :, 2] < 60)
    assert not red.any(), "the red wall left the scene"


def test_a_camera_whose_noise_changes_draws_it_from_its_seed_again() -> None:
    """update_camera: the noisy camera's deviation goes from 0 to 0.05, its generator restarts from the seed each
    time (two updates, the same pixels); a change of size is refused."""
    with started([backdrop()], SUN, "tiny") as pool:
        clean = frame(pool, NOISY)
        noisy_spec = CameraSpec("noisy", W, H, HFOV, 0.05, 50.0, noise_stddev=0.05, seed=3)
        pool.update_camera(NOISY, noisy_spec)
        first = frame(pool, NOISY)
        frame(pool, NOISY)  # the generator moves on ...
        pool.update_camera(NOISY, noisy_spec)  # ... and starts again from the seed
        again = frame(pool, NOISY)
        spread = float((first.astype(float) - clean).std())
        assert 0.05 * 255 * 0.8 < spread < 0.05 * 255 * 1.2, spread
        assert np.array_equal(first, again)
        with pytest.raises(ValueError, match="only its noise"):
            pool.update_camera(NOISY, CameraSpec("noisy", W * 2, H, HFOV, 0.05, 50.0, seed=3))


def test_a_worker_that_dies_during_an_edit_is_started_again_and_its_frame_dropped() -> None:
    """The worker is stopped (SIGSTOP), sent an edit and a request, then killed: the pool starts it again on the
    edited scene, drops the frame it owed (`dropped`: the caller counts it skipped) and renders the next one with
    the edit in it; a death outside an edit still breaks the pool."""
    with started([backdrop()], SUN, "tiny") as pool:
        pid = pool.pids[0]
        assert pid is not None
        os.kill(pid, signal.SIGSTOP)
        pool.edit(added=(wall("late", RED, 0.0),))
        pool.request(RGB, 5, AHEAD, {})
        os.kill(pid, signal.SIGKILL)
        assert pool.collect(wait_for=RGB, timeout=WAIT) == []
        assert pool.dropped() == [RGB]
        assert pool.pids[0] != pid
        centre = frame(pool, RGB, 6)[H // 2, W // 2]
        assert centre[0] > 150 and centre[1] < 60, f"the wall added by the edit is drawn: {centre}"
        again = pool.pids[0]
        assert again is not None
        os.kill(again, signal.SIGKILL)
        wait_until(lambda: pool.exited(0), WAIT, "the worker to end")
        with pytest.raises(RuntimeError, match="died"):
            pool.request(RGB, 7, AHEAD, {})


@pytest.fixture
def empty_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    yield tmp_path / "simbot"


@pytest.mark.skipif(NO_EGL is not None, reason=NO_EGL or "")
def test_a_texture_is_mipmapped_once_into_the_cache_and_drawn_from_it_the_same(empty_cache: Path) -> None:
    """A textured wall seen small (a far mip level): the first pool builds the chain and keeps it under
    $XDG_CACHE_HOME/simbot, keyed by the image's content; a second pool uploads it from there and draws the same
    pixels."""
    far = body_of("far", box_model((0.1, 4.0, 4.0), (1.0, 1.0, 1.0, 1.0), texture=TEXTURE), True, at(30.0, 0.0))
    with started([far], SUN, "gl") as pool:
        built = frame(pool)
    key = texture_cache.content_key(str(TEXTURE))
    assert key is not None
    cached = list((empty_cache / f"textures-{texture_cache.VERSION}" / key).glob("*.npz"))
    assert len(cached) == 1, "one chain, for this image and this GL renderer"
    with started([far], SUN, "gl") as pool:
        uploaded = frame(pool)
    assert np.array_equal(built, uploaded)
    assert len({tuple(p) for p in built.reshape(-1, 3)}) > 4, "the texture shows (not one flat colour)"
