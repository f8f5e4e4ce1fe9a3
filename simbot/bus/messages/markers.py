"""visualization_msgs: markers, the world's shapes as RViz and Foxglove draw them."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from simbot.bus.messages.geometry import pose, vector3
from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import ColorRGBA, CompressedImage, Duration, Header, Marker, MarkerArray, MeshFile
from simbot.bus.messages.values import Floats, floats, three

NO_COLOUR = (0.0, 0.0, 0.0, 0.0)
"""A mesh marker's colour when the mesh's own materials (and textures) are to be drawn."""


def marker(
    ns: int,
    frame: str,
    group: str,
    index: int,
    kind: int,
    xyz: Floats,
    quat_xyzw: Floats,
    scale: Floats,
    rgba: Floats,
    mesh: str = "",
) -> Marker:
    """visualization_msgs/Marker to ADD: a shape `kind` (Marker.CUBE, ...) in `frame`, marker namespace
    `group` and id `index`; `mesh` the URI a MESH_RESOURCE names, its own materials drawn when `rgba`
    is NO_COLOUR. Frame-locked: a viewer moves it with its frame."""
    r, g, b, a = floats(rgba, 4, "colour (r, g, b, a)")
    return Marker(
        header=header(ns, frame),
        ns=group,
        id=int(index),
        type=int(kind),
        action=Marker.ADD,
        pose=pose(xyz, quat_xyzw),
        scale=vector3(*three(scale, "scale")),
        color=ColorRGBA(r=r, g=g, b=b, a=a),
        lifetime=Duration(sec=0, nanosec=0),
        frame_locked=True,
        points=[],
        colors=[],
        texture_resource="",
        texture=CompressedImage(header=header(0, ""), format="", data=np.zeros(0, np.uint8)),
        uv_coordinates=[],
        text="",
        mesh_resource=mesh,
        mesh_file=MeshFile(filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=bool(mesh) and (r, g, b, a) == NO_COLOUR,
    )


def restamped(marker: Marker, stamp: Header) -> Marker:
    """`marker` with the header `stamp` (its frame and time): a scene of thousands of markers, built
    once each, stamped anew whenever it is sent again."""
    again = object.__new__(Marker)  # copy.copy's shallow copy, without its protocol: 2 µs, not 4
    again.__dict__.update(marker.__dict__)
    again.header = stamp
    return again


def delete_all(ns: int, frame: str) -> Marker:
    """The Marker that clears what a viewer holds: the head of an array that is the whole scene."""
    blank = marker(ns, frame, "", 0, Marker.CUBE, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), (1.0, 1.0, 1.0), NO_COLOUR)
    blank.action = Marker.DELETEALL
    return blank


def marker_array(markers: Iterable[Any]) -> MarkerArray:
    """visualization_msgs/MarkerArray holding `markers`."""
    return MarkerArray(markers=list(markers))
