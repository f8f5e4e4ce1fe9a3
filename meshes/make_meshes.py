#!/usr/bin/env python3
"""Write the Flexley Tug's visual meshes as binary STL files, in millimetres.

Every mesh is a *loft*: a stack of closed rings (each counter-clockwise seen from +Z,
all with the same number of points) joined by quads and closed by a fan at both ends.
A box, a chamfered chassis, a bevelled tyre and a sphere are all lofts of different
rings, so one helper builds them all. Triangles of zero area (at a sphere's poles) are
dropped. The output is deterministic: the same bytes on every run.

The robot's SDF scales these meshes by 0.001, so 1 unit here is 1 mm.

    python3 meshes/make_meshes.py [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

Triangles = NDArray[np.float64]  # shape (n, 3, 3): n triangles of three xyz vertices

SEGMENTS = 48  # points on a circle


def ring(profile: NDArray[np.float64], z: float) -> NDArray[np.float64]:
    """Lift a 2-D profile (N, 2) to a ring of N xyz points at height z."""
    return np.column_stack([profile, np.full(len(profile), z)])


def circle(radius: float, n: int = SEGMENTS) -> NDArray[np.float64]:
    """Counter-clockwise n-gon of the given radius, centred on the origin."""
    a = 2.0 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(a), np.sin(a)])


def chamfered_rect(lx: float, ly: float, c: float) -> NDArray[np.float64]:
    """Counter-clockwise octagon: an lx x ly rectangle with its corners cut by c."""
    x, y = lx / 2.0, ly / 2.0
    return np.array(
        [[x, -y + c], [x, y - c], [x - c, y], [-x + c, y], [-x, y - c], [-x, -y + c], [-x + c, -y], [x - c, -y]]
    )


def loft(rings: list[NDArray[np.float64]]) -> Triangles:
    """Closed, outward-facing surface through rings stacked bottom to top."""
    tris: list[NDArray[np.float64]] = []
    for lo, hi in zip(rings[:-1], rings[1:], strict=True):
        lo1, hi1 = np.roll(lo, -1, axis=0), np.roll(hi, -1, axis=0)
        tris += [np.stack([lo, lo1, hi1], axis=1), np.stack([lo, hi1, hi], axis=1)]
    for cap, up in ((rings[0], False), (rings[-1], True)):
        centre = np.broadcast_to(cap.mean(axis=0), cap.shape)
        nxt = np.roll(cap, -1, axis=0)
        tris.append(np.stack([centre, cap, nxt] if up else [centre, nxt, cap], axis=1))
    out = np.concatenate(tris)
    area = np.linalg.norm(np.cross(out[:, 1] - out[:, 0], out[:, 2] - out[:, 0]), axis=1)
    kept: Triangles = out[area > 1e-9]
    return kept


def prism(profile: NDArray[np.float64], z0: float, z1: float) -> Triangles:
    """The profile extruded from z0 to z1."""
    return loft([ring(profile, z0), ring(profile, z1)])


def write_stl(path: Path, tris: Triangles) -> None:
    """Write triangles as a binary STL with unit facet normals."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tris
    header = f"simbot {path.name} (mm)".encode().ljust(80, b" ")
    with open(path, "wb") as f:
        f.write(header + np.uint32(len(tris)).astype("<u4").tobytes() + rec.tobytes())


def chassis() -> Triangles:
    """Tug body, 2100 x 500 x 230 centred: chamfered corners, a bumper band, bevelled top."""
    levels = [(-115, 15), (-100, 0), (-40, 0), (-40, 8), (90, 8), (115, 30)]  # (z, inset)
    return loft([ring(chamfered_rect(2100 - 2 * i, 500 - 2 * i, 60 - i), z) for z, i in levels])


def wheel() -> Triangles:
    """Wheel, radius 75 and width 50 along Z, centred, with bevelled tyre shoulders."""
    levels = [(-25, 68), (-20, 75), (20, 75), (25, 68)]  # (z, radius)
    return loft([ring(circle(r), z) for z, r in levels])


def castor() -> Triangles:
    """Castor ball: sphere of radius 25, centred (a UV sphere as a loft of latitudes)."""
    lat = np.linspace(-np.pi / 2, np.pi / 2, SEGMENTS // 2 + 1)
    return loft([ring(circle(25 * np.cos(t)), 25 * np.sin(t)) for t in lat])


def lidar() -> Triangles:
    """Lidar, r 50 x 50 along Z centred: a body with a smaller scanning head on top."""
    return np.concatenate([prism(circle(50), -25, 10), prism(circle(38), 10, 25)])


MESHES = {"chassis": chassis, "wheel": wheel, "castor": castor, "lidar": lidar}


def main() -> None:
    """Write every mesh into --out (default: this script's folder)."""
    parser = argparse.ArgumentParser(description="Write simbot's STL meshes (mm).")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    out: Path = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    for name, build in MESHES.items():
        write_stl(out / f"{name}.stl", build())


if __name__ == "__main__":
    main()
