"""Intel Embree 4's C API, as much of it as the ray engine needs, called through ctypes on the
library the `embreex` wheel ships.

Why not embreex's own Python classes: they copy a mesh's vertices from Python one index at a time
(40 ms for the warehouse's moving parts) and cannot move a geometry once built. Embree itself
shares numpy's buffers (no copy), instances a scene under a transform, and takes an array of
instances whose transforms are one shared buffer: posing every moving part anew is one numpy write
and three calls (`InstanceArray.pose`). Rays go in packets of 16 (`Packets`): 0.5 µs of ctypes a
packet, where a call a ray would cost more than Embree's work.

Layouts are Embree 4.4's (`rtcore_ray.h`: RTCRayHit16 with one instance level and instance arrays;
`rtcore_common.h`, `rtcore_buffer.h`, `rtcore_geometry.h` for the enumerations).
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import util
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

Floats = npt.NDArray[np.float64]
GEOMETRY_TRIANGLE, GEOMETRY_INSTANCE, GEOMETRY_INSTANCE_ARRAY = 0, 121, 122
BUFFER_INDEX, BUFFER_VERTEX, BUFFER_TRANSFORM = 0, 1, 23
FORMAT_UINT, FORMAT_UINT3, FORMAT_FLOAT3, FORMAT_FLOAT3X4_COLUMN_MAJOR = 0x5001, 0x5003, 0x9003, 0x9234
FORMAT_QUATERNION_DECOMPOSITION = 0xB001
"""16 floats: scale (3), skew (3), shift (3), the rotation as w, x, y, z, the translation (3)."""
SCENE_FLAG_ROBUST = 1 << 2
"""Watertight: a ray through a shared edge or corner meets one of its triangles (the pole of a sphere)."""
INVALID = 0xFFFFFFFF
"""Embree's invalid geometry id: no hit."""
LANES = 16
"""Rays a packet."""
ROWS = 21
"""A packet's rows of 16: the ray's origin (3), tnear, direction (3), time, tfar, mask, id, flags;
the hit's normal (3), u, v, primID, geomID, instID, instPrimID."""
ORIGIN, TNEAR, DIRECTION, TFAR, MASK = 0, 3, 4, 8, 9
GEOM_ID, INST_ID, INST_PRIM_ID = 18, 19, 20
_PACKET_BYTES = ROWS * LANES * 4
_ALIGN = 64


@functools.cache
def library() -> ctypes.CDLL | None:
    """Embree's library inside the embreex wheel (`embreex.libs`, `.dylibs` or the package itself),
    its functions typed; None where embreex is not installed or ships no library there."""
    spec = util.find_spec("embreex")
    if spec is None or spec.origin is None:
        return None
    package = Path(spec.origin).parent
    found = sorted(
        path
        for folder in (package.parent / "embreex.libs", package / ".dylibs", package)
        for pattern in ("libembree4*", "embree4*.dll")
        for path in folder.glob(pattern)
    )
    return _typed(ctypes.CDLL(str(found[0]))) if found else None


def _typed(lib: ctypes.CDLL) -> ctypes.CDLL:
    """Gives each function the engine calls its C signature (pointers stay 64-bit)."""
    p, u, i, s = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
    signatures: dict[str, tuple[object, list[object]]] = {
        "rtcNewDevice": (p, [ctypes.c_char_p]),
        "rtcReleaseDevice": (None, [p]),
        "rtcGetDeviceError": (i, [p]),
        "rtcNewScene": (p, [p]),
        "rtcReleaseScene": (None, [p]),
        "rtcSetSceneFlags": (None, [p, i]),
        "rtcCommitScene": (None, [p]),
        "rtcNewGeometry": (p, [p, i]),
        "rtcSetSharedGeometryBuffer": (None, [p, i, u, i, p, s, s, s]),
        "rtcUpdateGeometryBuffer": (None, [p, i, u]),
        "rtcSetGeometryInstancedScene": (None, [p, p]),
        "rtcSetGeometryInstancedScenes": (None, [p, p, s]),
        "rtcSetGeometryTransform": (None, [p, u, i, p]),
        "rtcCommitGeometry": (None, [p]),
        "rtcAttachGeometry": (u, [p, p]),
        "rtcReleaseGeometry": (None, [p]),
        "rtcIntersect16": (None, [p, p, p, p]),
    }
    for name, (result, arguments) in signatures.items():
        function = getattr(lib, name)
        function.restype = result
        function.argtypes = arguments
    return lib


@dataclass
class Device:
    """One Embree device (its thread pool and memory); every scene of a world is made on it."""

    lib: ctypes.CDLL
    handle: int = field(init=False)

    def __post_init__(self) -> None:
        self.handle = self.lib.rtcNewDevice(None)
        if not self.handle:
            raise RuntimeError("ray engine: Embree could not make a device")

    def check(self, what: str) -> None:
        """Raises where Embree recorded an error (a programming error here, not a user's)."""
        if code := self.lib.rtcGetDeviceError(self.handle):
            raise RuntimeError(f"ray engine: Embree error {code} while {what}")

    def __del__(self) -> None:
        if getattr(self, "handle", None):
            self.lib.rtcReleaseDevice(self.handle)


@dataclass
class Scene:
    """An Embree scene: triangle meshes (`triangles`) and instances of other scenes, built on `commit`.
    It holds the numpy buffers Embree reads and the scenes it instances, so they live as long as it."""

    device: Device
    handle: int = field(init=False)
    _kept: list[object] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.handle = self.device.lib.rtcNewScene(self.device.handle)
        self.device.lib.rtcSetSceneFlags(self.handle, SCENE_FLAG_ROBUST)

    def triangles(self, triangles: Floats) -> int:
        """A mesh of K×3×3 corners (no shared vertices); returns its geometry id."""
        vertices = np.ascontiguousarray(triangles.reshape(-1, 3), dtype=np.float32)
        vertices = np.concatenate([vertices, np.zeros((1, 3), np.float32)])  # Embree reads 16 bytes at the last
        indices = np.arange(len(triangles) * 3, dtype=np.uint32).reshape(-1, 3)
        geometry = self._geometry(GEOMETRY_TRIANGLE)
        lib = self.device.lib
        lib.rtcSetSharedGeometryBuffer(
            geometry, BUFFER_VERTEX, 0, FORMAT_FLOAT3, vertices.ctypes.data, 0, 12, len(indices) * 3
        )
        lib.rtcSetSharedGeometryBuffer(
            geometry, BUFFER_INDEX, 0, FORMAT_UINT3, indices.ctypes.data, 0, 12, len(indices)
        )
        self._kept += [vertices, indices]
        return self._attach(geometry)

    def instance(self, scene: Scene) -> int:
        """`scene` where it is (the identity transform); returns the instance's geometry id."""
        geometry = self._geometry(GEOMETRY_INSTANCE)
        identity = np.ascontiguousarray(np.eye(4)[:3].T, dtype=np.float32)
        self.device.lib.rtcSetGeometryInstancedScene(geometry, scene.handle)
        self.device.lib.rtcSetGeometryTransform(geometry, 0, FORMAT_FLOAT3X4_COLUMN_MAJOR, identity.ctypes.data)
        self._kept.append(scene)
        return self._attach(geometry)

    def instance_array(self, scenes: Sequence[Scene], which: Sequence[int]) -> InstanceArray:
        """Instances of `scenes`, the k-th of `scenes[which[k]]`, posed by `InstanceArray.pose`."""
        geometry = self._geometry(GEOMETRY_INSTANCE_ARRAY)
        array = InstanceArray(self.device, geometry, np.asarray(which, dtype=np.uint32))
        handles = (ctypes.c_void_p * len(scenes))(*[scene.handle for scene in scenes])
        lib = self.device.lib
        lib.rtcSetGeometryInstancedScenes(geometry, handles, len(scenes))
        lib.rtcSetSharedGeometryBuffer(
            geometry, BUFFER_INDEX, 0, FORMAT_UINT, array.which.ctypes.data, 0, 4, len(which)
        )
        lib.rtcSetSharedGeometryBuffer(
            geometry,
            BUFFER_TRANSFORM,
            0,
            FORMAT_QUATERNION_DECOMPOSITION,
            array.transforms.ctypes.data,
            0,
            64,
            len(which),
        )
        array.id = self._attach(geometry)
        self._kept += [*scenes, array]
        return array

    def commit(self) -> None:
        self.device.lib.rtcCommitScene(self.handle)
        self.device.check("building a scene")

    def _geometry(self, kind: int) -> int:
        return int(self.device.lib.rtcNewGeometry(self.device.handle, kind))

    def _attach(self, geometry: int) -> int:
        lib = self.device.lib
        lib.rtcCommitGeometry(geometry)
        geometry_id = int(lib.rtcAttachGeometry(self.handle, geometry))
        lib.rtcReleaseGeometry(geometry)
        self.device.check("adding a geometry")
        return geometry_id

    def __del__(self) -> None:
        if getattr(self, "handle", None):
            self.device.lib.rtcReleaseScene(self.handle)


@dataclass
class InstanceArray:
    """Instances whose transforms are one shared buffer: `pose` writes them and tells Embree. The
    scene that holds the array is committed again after (`Scene.commit`)."""

    device: Device
    geometry: int
    which: npt.NDArray[np.uint32]
    transforms: npt.NDArray[np.float32] = field(init=False)
    """K×16: each instance's pose as Embree's quaternion decomposition (unit scale, no skew or shift)."""
    id: int = -1

    def __post_init__(self) -> None:
        self.transforms = np.zeros((len(self.which), 16), np.float32)
        self.transforms[:, :3] = 1.0

    def pose(self, poses: Floats) -> None:
        """Each instance at its pose: K rows of a position and a unit quaternion x, y, z, w (PyBullet's order)."""
        self.transforms[:, 13:16] = poses[:, :3]
        self.transforms[:, 9] = poses[:, 6]
        self.transforms[:, 10:13] = poses[:, 3:6]
        self.device.lib.rtcUpdateGeometryBuffer(self.geometry, BUFFER_TRANSFORM, 0)
        self.device.lib.rtcCommitGeometry(self.geometry)


@dataclass(frozen=True)
class Hits:
    """Where each ray first met the scene: its `t` (NaN: no hit), and the instance and geometry hit."""

    t: Floats
    instance: npt.NDArray[np.int64]
    """The top-level geometry id of the instance hit (-1: none)."""
    index: npt.NDArray[np.int64]
    """Which instance of an instance array (-1: none)."""
    geometry: npt.NDArray[np.int64]
    """The geometry hit inside the instanced scene (-1: none)."""


def cast(scene: Scene, origins: Floats, directions: Floats, tnear: Floats | float, tfar: float) -> Hits:
    """First hits of the rays origin + t·direction, t in [tnear, tfar], in packets of LANES."""
    count = len(origins)
    packets = _packets(max(1, -(-count // LANES)))
    rays, words = packets.rays, packets.rays.view(np.uint32)
    for row, values in ((ORIGIN, origins), (DIRECTION, directions), (TNEAR, tnear), (TFAR, tfar)):
        _fill(rays, row, values, count)
    words[:, GEOM_ID : INST_ID + 1, :] = INVALID
    valid = packets.valid(count)
    intersect, handle, base = scene.device.lib.rtcIntersect16, scene.handle, rays.ctypes.data
    for packet in range(len(rays)):
        intersect(valid + packet * LANES * 4, handle, base + packet * _PACKET_BYTES, None)
    ids = words[:, GEOM_ID:, :].view(np.int32).transpose(1, 0, 2).reshape(3, -1)[:, :count].astype(np.int64)
    t = rays[:, TFAR, :].reshape(-1)[:count].astype(np.float64)
    return Hits(np.where(ids[0] >= 0, t, np.nan), ids[1], ids[2], ids[0])  # Embree's INVALID reads as -1


@dataclass
class _Packets:
    """An aligned buffer of ray packets (packets × ROWS × LANES), kept for the next cast of as many,
    its rays' mask, time, id and flags set once."""

    rays: npt.NDArray[np.float32]
    _valid: npt.NDArray[np.int32]
    _count: int = -1

    def valid(self, count: int) -> int:
        """The address of the lanes' valid flags: the first `count` lanes valid (-1), the rest not."""
        if count != self._count:
            self._valid[:count], self._valid[count:], self._count = -1, 0, count
        return int(self._valid.ctypes.data)


@functools.lru_cache(maxsize=8)
def _packets(count: int) -> _Packets:
    rays = _aligned(count * ROWS * LANES, np.float32).reshape(count, ROWS, LANES)
    rays.view(np.uint32)[:, MASK, :] = INVALID
    return _Packets(rays, _aligned(count * LANES, np.int32))


def _aligned(size: int, dtype: type[np.float32] | type[np.int32]) -> npt.NDArray[Any]:
    """`size` zeros at a 64-byte boundary: Embree loads a packet's rays and its valid flags with
    aligned vector loads (AVX-512 faults on a misaligned one; AVX2 had hidden it)."""
    raw = np.zeros(size + _ALIGN // 4, dtype)
    shift = (-raw.ctypes.data % _ALIGN) // 4
    return raw[shift : shift + size]


def _fill(rays: npt.NDArray[np.float32], row: int, values: Floats | float, count: int) -> None:
    """Writes the first `count` rays' `values` (count×k, or one number for all) into `row` onwards."""
    if np.isscalar(values):
        rays[:, row, :] = values
        return
    data = np.asarray(values).reshape(count, -1)
    width, full = data.shape[1], count // LANES
    rays[:full, row : row + width, :].transpose(0, 2, 1)[...] = data[: full * LANES].reshape(full, LANES, width)
    if count > full * LANES:
        rays[full, row : row + width, : count - full * LANES] = data[full * LANES :].T
