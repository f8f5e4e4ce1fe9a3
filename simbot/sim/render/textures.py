"""Textures for the OpenGL renderer, decoded and mipmapped once, then kept on disk.

Decoding a world's textures and building their mipmaps took a worker half a second of its start
in the warehouse on two cores, most of it llvmpipe compiling its blit for each size of texture.
The mip chain GL builds is kept in the user's cache (`cache_dir()`: `$XDG_CACHE_HOME/simbot`, else
`~/.cache/simbot`), keyed by the image file's content and the GL renderer that built it; a later
worker, in this run or another, uploads the levels as they are (`glTexImage2D` per level): the
same texels, no decoding, no blit. A cache file is written whole and renamed into place, so a
worker reading it meanwhile finds it whole or not at all; one that cannot be read is built anew.
Where the levels cannot be uploaded directly (no EGL entry points), GL builds them each time.
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

VERSION = 1
"""Of the cache's layout: a change moves it to a new folder."""
GL_TEXTURE_2D, GL_RGB, GL_RGB8, GL_UNSIGNED_BYTE, GL_UNPACK_ALIGNMENT = 0x0DE1, 0x1907, 0x8051, 0x1401, 0x0CF5


def cache_dir() -> Path:
    """simbot's folder in the user's cache: `$XDG_CACHE_HOME/simbot`, else `~/.cache/simbot`."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "simbot"


@cache
def _digest(path: str, mtime_ns: int, size: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:32]


def content_key(path: str) -> str | None:
    """The image file's content digest (worked out once per file and version of it); None if it is missing."""
    try:
        stat = os.stat(path)
    except OSError:
        return None
    return _digest(path, stat.st_mtime_ns, stat.st_size)


def _folder(key: str) -> Path:
    return cache_dir() / f"textures-{VERSION}" / key


def known(path: str) -> bool:
    """Whether a renderer has decoded this image before (it is in the cache): it decodes."""
    key = content_key(path)
    return key is not None and _folder(key).is_dir()


def upload(ctx: Any, path: str, device: str) -> Any | None:
    """The image as a mipmapped texture of `ctx`, from the cache where it holds it (else decoded,
    built by GL and cached); None where the file cannot be read."""
    key = content_key(path)
    if key is None:
        return None
    where = _folder(key) / f"{hashlib.sha256(device.encode()).hexdigest()[:16]}.npz"
    stored = _read(where)
    if stored is not None and (texture := _from_levels(ctx, stored)) is not None:
        return texture
    import cv2

    image = cv2.imread(path, cv2.IMREAD_COLOR)
    if image is None:
        return None
    rgb = np.ascontiguousarray(image[::-1, :, ::-1])  # GL's first row is the image's bottom one
    texture = ctx.texture((rgb.shape[1], rgb.shape[0]), 3, rgb.tobytes(), alignment=1)
    texture.build_mipmaps()
    width, height = rgb.shape[1], rgb.shape[0]
    built = [np.frombuffer(texture.read(level=i, alignment=1), np.uint8) for i in range(_count(width, height))]
    _write(where, built, width, height)
    return texture


def _count(width: int, height: int) -> int:
    """Levels of a full mip chain: down to 1×1."""
    return max(width, height).bit_length()


def _size(width: int, height: int, level: int) -> tuple[int, int]:
    return max(1, width >> level), max(1, height >> level)


def _read(where: Path) -> tuple[int, int, list[np.ndarray]] | None:
    try:
        with np.load(where) as stored:
            width, height = (int(v) for v in stored["size"])
            levels = [stored[f"level{i}"] for i in range(_count(width, height))]
    except (OSError, KeyError, ValueError) as exc:
        if where.exists():
            log.warning("texture cache %s cannot be read (%s); the texture is built anew", where, exc)
        return None
    expected = [w * h * 3 for w, h in (_size(width, height, i) for i in range(len(levels)))]
    if [len(level) for level in levels] != expected:
        log.warning("texture cache %s holds levels of the wrong sizes; the texture is built anew", where)
        return None
    return width, height, levels


def _write(where: Path, levels: list[np.ndarray], width: int, height: int) -> None:
    """Whole or not at all: written beside, then renamed into place."""
    try:
        where.parent.mkdir(parents=True, exist_ok=True)
        partial = where.with_name(f".{where.stem}.{os.getpid()}.npz")
        arrays: dict[str, Any] = {"size": np.array([width, height])}
        arrays |= {f"level{i}": level for i, level in enumerate(levels)}
        np.savez(partial, **arrays)
        os.replace(partial, where)
    except OSError as exc:
        log.warning("texture cache %s cannot be written (%s); the texture is built each time", where, exc)


def _from_levels(ctx: Any, stored: tuple[int, int, list[np.ndarray]]) -> Any | None:
    """A texture with every level uploaded as stored; None where GL's entry points cannot be had."""
    entry = _entry_points()
    if entry is None:
        return None
    tex_image, pixel_store = entry
    width, height, levels = stored
    texture = ctx.texture((width, height), 3, levels[0].tobytes(), alignment=1)
    texture.use(0)  # bound to GL_TEXTURE_2D, where the levels go
    pixel_store(GL_UNPACK_ALIGNMENT, 1)
    for level, data in enumerate(levels[1:], 1):
        w, h = _size(width, height, level)
        tex_image(GL_TEXTURE_2D, level, GL_RGB8, w, h, 0, GL_RGB, GL_UNSIGNED_BYTE, data.ctypes.data)
    return texture


@cache
def _entry_points() -> tuple[Any, Any] | None:
    """glTexImage2D and glPixelStorei of the current EGL context (moderngl uploads only level 0)."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return None
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    image, store = egl.eglGetProcAddress(b"glTexImage2D"), egl.eglGetProcAddress(b"glPixelStorei")
    if not image or not store:
        return None
    u, i, p = ctypes.c_uint, ctypes.c_int, ctypes.c_void_p
    return ctypes.CFUNCTYPE(None, u, i, i, i, i, i, u, u, p)(image), ctypes.CFUNCTYPE(None, u, i)(store)
