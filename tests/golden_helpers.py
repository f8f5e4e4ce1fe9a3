"""Golden runs pinned by what the simulator decides: every message decoded, field by field.

A recording is a run's messages per key, each turned into columns by field path
(`pose.position.x`, `transforms[].header.frame_id`, `ranges`): integers, booleans, strings, frame
ids, stamps and the lengths of arrays are compared exactly; floats within the tolerance
`TOLERANCES` states for their field, derived from how the field is computed; the bytes of an
image (drawn by GL) by their SHA-256, compared only where the rasteriser is the one they were
recorded with. A float field without a stated tolerance is an error, so a new key must say how
exactly it is pinned.

Also here: what the machine is (`machine`), and the OpenBLAS kernels this CPU can run
(`kernel_environments`): the behaviour test runs the same golden run under each and requires
the same bytes, so a published value that a CPU-chosen BLAS kernel decides fails on any machine.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import platform
import re
import subprocess
import sys
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import decode

Columns = dict[str, npt.NDArray[Any]]
"""A key's messages as columns: field path → every value of that field, in message order."""
IMAGE = "sensor_msgs/msg/Image"
POINTS = "sensor_msgs/msg/PointCloud2"
DIGEST = "#sha256"
"""Suffix of a column holding the SHA-256 of each message's bytes in a field (image pixels)."""
LENGTH = "#"
"""Suffix of a column holding the length of each array or list field."""
POINT_FIELD_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
"""sensor_msgs/PointField datatypes as numpy dtypes (little-endian: simbot writes no other)."""


@dataclass(frozen=True)
class Tolerance:
    """How far a float may move between a recording and a run: |a − b| ≤ abs + rel·|b|."""

    rel: float
    abs: float
    why: str

    def holds(self, now: npt.NDArray[np.float64], recorded: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        return np.isclose(now, recorded, rtol=self.rel, atol=self.abs, equal_nan=True)


STATE = Tolerance(
    1e-9,
    1e-12,
    "a float64 of PyBullet's state (a pose, a velocity, a joint's angle) taken through a few dozen "
    "operations: a CPU's last bit is 1.1e-16 of it and stays under 1e-12 after them; the smallest "
    "change of behaviour (a noise draw, a step of the solver, 1 µm) moves it by 1e-6 or more",
)
DERIVED = Tolerance(
    1e-9,
    1e-9,
    "a difference quotient of state, an IMU's Δv/Δt at 200 Hz: the velocity's last bit (1e-16 m/s) "
    "divided by 5 ms is 2e-14 m/s²; 1e-9 stays six orders below its noise (stddev 1.7e-2 m/s²)",
)
CONSTANT = Tolerance(
    1e-12,
    1e-15,
    "made from SDF parameters by a handful of operations (an intrinsic from tan(fov/2), a variance "
    "from a stddev): correctly rounded libm and IEEE arithmetic move it by an ulp at most",
)
SINGLE = Tolerance(
    2.0**-22,
    1e-12,
    "a float32 rounded from a float64 (a range, a point, a colour): a last-bit difference before "
    "the rounding moves it by one float32 step (2^-23 relative) at most",
)

TOLERANCES: dict[str, dict[str, Tolerance]] = {
    "geometry_msgs/msg/PoseStamped": {"pose.*": STATE},
    "geometry_msgs/msg/Twist": {"linear.*": CONSTANT, "angular.*": CONSTANT},
    "nav_msgs/msg/Odometry": {"pose.pose.*": STATE, "twist.twist.*": STATE, "*.covariance": CONSTANT},
    "tf2_msgs/msg/TFMessage": {"transforms[].transform.*": STATE},
    "sensor_msgs/msg/Imu": {
        "orientation.*": STATE,
        "angular_velocity.*": STATE,
        "linear_acceleration.*": DERIVED,
        "*_covariance": CONSTANT,
    },
    "sensor_msgs/msg/JointState": {"position": STATE, "velocity": STATE, "effort": STATE},
    "sensor_msgs/msg/LaserScan": {
        "angle_*": SINGLE,
        "range_*": SINGLE,
        "time_increment": SINGLE,
        "scan_time": SINGLE,
        "ranges": SINGLE,
        "intensities": SINGLE,
    },
    POINTS: {"data.*": SINGLE},
    "sensor_msgs/msg/CameraInfo": {"d": CONSTANT, "k": CONSTANT, "r": CONSTANT, "p": CONSTANT},
    "visualization_msgs/msg/MarkerArray": {
        "markers[].pose.*": STATE,
        "markers[].scale.*": CONSTANT,
        "markers[].color.*": SINGLE,
        "markers[].colors[].*": SINGLE,
        "markers[].points[].*": STATE,
    },
    "nav_msgs/msg/OccupancyGrid": {"info.resolution": SINGLE, "info.origin.*": CONSTANT},
}
"""Per message type, per field path (shell patterns): the tolerance of each float field and why."""


def tolerance(typename: str, path: str) -> Tolerance:
    """The stated tolerance of a float field; AssertionError where none is stated."""
    for pattern, stated in TOLERANCES.get(typename, {}).items():
        if fnmatchcase(path, pattern):
            return stated
    raise AssertionError(f"no tolerance stated for the float field {path!r} of {typename}: add it to TOLERANCES")


# --- messages into columns ------------------------------------------------------------------


def _flatten(msg: Any, path: str, out: defaultdict[str, list[Any]]) -> None:
    """Appends each field of `msg` to its column (`path` is the prefix of its fields' paths)."""
    for item in fields(msg):
        if item.name.startswith("__") or item.name.isupper():  # the type name; constants
            continue
        _value(getattr(msg, item.name), path + item.name, out)


def _value(value: Any, path: str, out: defaultdict[str, list[Any]]) -> None:
    if hasattr(value, "__msgtype__"):
        _flatten(value, path + ".", out)
    elif isinstance(value, list):
        out[path + LENGTH].append(len(value))
        for element in value:
            _value(element, path + "[]", out)
    elif isinstance(value, np.ndarray):
        out[path + LENGTH].append(len(value))
        if value.dtype == np.uint8:
            out[path + DIGEST].append(hashlib.sha256(value.tobytes()).hexdigest())
        else:
            out[path].extend(value.tolist())
    else:
        out[path].append(value)


def _point_columns(msg: Any, out: defaultdict[str, list[Any]]) -> None:
    """A PointCloud2's data read through its fields (x, y, z, intensity...), one column each."""
    dtype = np.dtype(
        {
            "names": [f.name for f in msg.fields],
            "formats": [np.dtype(POINT_FIELD_TYPES[f.datatype]).newbyteorder("<") for f in msg.fields],
            "offsets": [f.offset for f in msg.fields],
            "itemsize": msg.point_step,
        }
    )
    points = np.frombuffer(msg.data.tobytes(), dtype=dtype)
    for name in dtype.names or ():
        out[f"data.{name}"].extend(points[name].tolist())


def columns(typename: str, payloads: Iterable[bytes], placeless: str) -> Columns:
    """The messages of one key as columns; `placeless` (the checkout's path) becomes `<repo>` in strings."""
    out: defaultdict[str, list[Any]] = defaultdict(list)
    for payload in payloads:
        msg = decode(payload, typename)
        _flatten(msg, "", out)
        if typename == POINTS:
            out.pop("data" + DIGEST)
            _point_columns(msg, out)
    return {path: _array(values, placeless) for path, values in out.items() if values}


def _array(values: list[Any], placeless: str) -> npt.NDArray[Any]:
    if values and isinstance(values[0], str):
        return np.array([v.replace(placeless, "<repo>") for v in values])
    if values and isinstance(values[0], float):
        return np.array(values, dtype=np.float64)
    return np.array(values, dtype=np.int64)


# --- a recording and its comparison ---------------------------------------------------------


@dataclass
class Recording:
    """A golden run as columns: per key, its type and its columns."""

    types: dict[str, str]
    keys: dict[str, Columns]

    def save(self, path: Path) -> None:
        arrays = {f"{key}|{column}": values for key, cols in self.keys.items() for column, values in cols.items()}
        arrays["types"] = np.array(json.dumps(self.types, sort_keys=True))
        np.savez_compressed(path, allow_pickle=True, **arrays)  # numpy's default, named so **arrays types check

    @staticmethod
    def load(path: Path) -> Recording:
        with np.load(path) as data:
            types = json.loads(str(data["types"]))
            keys: dict[str, Columns] = {key: {} for key in types}
            for name in data.files:
                if name != "types":
                    key, column = name.split("|", 1)
                    keys[key][column] = data[name]
        return Recording(types, keys)


def differences(now: Recording, recorded: Recording, unpinned: Mapping[str, str]) -> list[str]:
    """One line per field that differs beyond its rule; `unpinned` maps a column suffix (an image's
    pixels) to the reason it is not compared."""
    found = []
    if sorted(now.keys) != sorted(recorded.keys):
        return [f"the published keys changed: {sorted(set(now.keys) ^ set(recorded.keys))}"]
    for key in sorted(now.keys):
        typename = now.types[key]
        if typename != recorded.types[key]:
            found.append(f"{key}: type {typename}, recorded {recorded.types[key]}")
            continue
        ours, theirs = now.keys[key], recorded.keys[key]
        if sorted(ours) != sorted(theirs):
            found.append(f"{key}: fields {sorted(set(ours) ^ set(theirs))} appear or vanish")
            continue
        for path in sorted(ours):
            if not any(path.endswith(suffix) for suffix in unpinned):
                found.extend(_column_difference(key, typename, path, ours[path], theirs[path]))
    return found


def _column_difference(
    key: str, typename: str, path: str, now: npt.NDArray[Any], recorded: npt.NDArray[Any]
) -> list[str]:
    where = f"{key} {path}"
    if now.shape != recorded.shape:
        return [f"{where}: {len(now)} values, recorded {len(recorded)}"]
    if now.dtype.kind != "f" or recorded.dtype.kind != "f":
        unequal = np.flatnonzero(now != recorded)
        if len(unequal):
            i = unequal[0]
            return [
                f"{where}: {len(unequal)} of {len(now)} differ, first #{i}: {now[i].item()!r}, "
                f"recorded {recorded[i].item()!r}"
            ]
        return []
    rule = tolerance(typename, path)
    off = np.flatnonzero(~rule.holds(now, recorded))
    if not len(off):
        return []
    i = off[0]
    worst = float(np.nanmax(np.abs(now[off] - recorded[off])))
    return [
        f"{where}: {len(off)} of {len(now)} values beyond rel {rule.rel:g} abs {rule.abs:g} (largest "
        f"difference {worst:.3g}), first #{i}: {now[i].item()!r}, recorded {recorded[i].item()!r}"
    ]


NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def text_differences(now: str, recorded: str, rule: Tolerance) -> list[str]:
    """Where two generated texts (a URDF, a COLLADA file) differ: outside their numbers exactly,
    their numbers within `rule` (a number printed to n digits may flip its last one where a CPU's
    last bit lands on the other side of the rounding)."""
    ours, theirs = NUMBER.split(now), NUMBER.split(recorded)
    if ours != theirs:
        i = next((i for i, (a, b) in enumerate(zip(ours, theirs)) if a != b), min(len(ours), len(theirs)))
        return [
            f"the text differs outside its numbers at piece #{i}: {ours[i : i + 1]!r}, recorded {theirs[i : i + 1]!r}"
        ]
    a = np.array([float(x) for x in NUMBER.findall(now)])
    b = np.array([float(x) for x in NUMBER.findall(recorded)])
    off = np.flatnonzero(~rule.holds(a, b))
    return [f"number #{i}: {a[i]!r}, recorded {b[i]!r} (rel {rule.rel:g}, abs {rule.abs:g})" for i in off[:10]]


# --- the machine ----------------------------------------------------------------------------

_OPENBLAS_CORE = """
import ctypes, glob, os, numpy
folder = os.path.dirname(numpy.__file__) + ".libs"
for path in sorted(glob.glob(os.path.join(folder, "*openblas*"))):
    lib = ctypes.CDLL(path)
    for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename"):
        function = getattr(lib, name, None)
        if function is not None:
            function.restype = ctypes.c_char_p
            print(function().decode())
            raise SystemExit
"""
"""Prints the kernel OpenBLAS chose in a fresh process (numpy's wheels bundle it in numpy.libs);
prints nothing where numpy uses another BLAS."""

KERNELS = {"Prescott": ("SSE3",), "Haswell": ("AVX2", "FMA3"), "Zen": ("AVX2", "FMA3"), "SkylakeX": ("AVX512_SKX",)}
"""OpenBLAS kernels (OPENBLAS_CORETYPE) and the CPU features each needs (numpy's names)."""


def _cpu_features() -> dict[str, bool]:
    from numpy._core._multiarray_umath import __cpu_features__

    return dict(__cpu_features__)


def openblas_core(env: Mapping[str, str] | None = None) -> str | None:
    """The kernel OpenBLAS picks in a process with `env` added; None where numpy has no OpenBLAS."""
    done = subprocess.run(
        [sys.executable, "-c", _OPENBLAS_CORE],
        env={**os.environ, **(env or {})},
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return done.stdout.strip() or None


def numpy_dispatch_mask() -> str:
    """numpy's runtime-dispatched CPU features this machine has (its SIMD paths beyond the
    baseline), as `NPY_DISABLE_CPU_FEATURES` takes them: masked, numpy runs its baseline loops."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    have = _cpu_features()
    return " ".join(feature for feature in __cpu_dispatch__ if have.get(feature))


@functools.cache
def kernel_environments() -> list[dict[str, str]]:
    """One environment per OpenBLAS kernel this CPU can run other than the one it picks (kernels
    that pick the same core once), each also masking numpy's dispatched SIMD paths."""
    default = openblas_core()
    if default is None:
        return []
    have, mask, seen = _cpu_features(), numpy_dispatch_mask(), {default}
    environments = []
    for name, needs in KERNELS.items():
        if not all(have.get(feature) for feature in needs):
            continue
        env = {"OPENBLAS_CORETYPE": name, **({"NPY_DISABLE_CPU_FEATURES": mask} if mask else {})}
        core = openblas_core(env)
        if core is not None and core not in seen:
            seen.add(core)
            environments.append(env)
    return environments


def cpu_model() -> str:
    """The CPU's model name, as the benchmarks name it above their tables (benchmarks/tables.py)."""
    spec = importlib.util.spec_from_file_location("tables", Path(__file__).parents[1] / "benchmarks" / "tables.py")
    assert spec is not None and spec.loader is not None
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    return str(tables.cpu_model())


def machine() -> dict[str, Any]:
    """What a recording was made on: the CPU, its SIMD features as numpy sees them, numpy's and
    OpenBLAS's versions and the kernel OpenBLAS picked."""
    blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    return {
        "cpu": cpu_model(),
        "simd": " ".join(sorted(feature for feature, on in _cpu_features().items() if on)),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "blas": f"{blas.get('name')} {blas.get('version')}",
        "openblas_core": openblas_core(),
    }
