"""Mesh materials as the OpenGL renderer shows them (real GL, skipped where no EGL context opens):
an OBJ whose MTL gives one triangle a colour and the other a texture, and a COLLADA file with the
same two materials, each seen face on, show each material's colour, and the texture's two halves,
where their triangles and texture coordinates put them."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from gl_helpers import NO_EGL
from test_materials import COLLADA, write_image, write_obj
from test_shading import AHEAD, DARK, SIZE, camera, drawing

from simbot.description import load_world
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.physics import Physics

pytestmark = pytest.mark.skipif(NO_EGL is not None, reason=NO_EGL or "")

DISTANCE = 3.0
"""The quads stand this far ahead of the camera, face on."""
FACE_ON = f"{DISTANCE} {{y}} -0.5 0 {-math.pi / 2} 0"
"""A visual pose turning a mesh's unit quad in its xy plane (normal +z) to face the camera along
−x: its x is then world z (up the image), its y world y (left in the image); {y} places it."""
RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)
"""RGB, as the colour image holds them."""


def pixel(y: float, z: float) -> tuple[int, int]:
    """(row, column) of the point (DISTANCE, y, z) for a camera at the origin looking along +x (fx = 100)."""
    cx = (SIZE - 1) / 2
    return round(cx - z / DISTANCE * 100.0), round(cx - y / DISTANCE * 100.0)


def test_obj_and_collada_show_each_material_where_its_triangles_are(tmp_path: Path) -> None:
    """Each quad: the lower-left triangle (image) textured, green below its middle (u < 0.5) and
    blue above; the upper-right one red. Lit by a white ambient light only, each shows its
    material's ambient (1 for these) times its colour or texture."""
    write_image(tmp_path / "stripes.png", GREEN[::-1], BLUE[::-1])  # BGR: u < 0.5 green, u ≥ 0.5 blue
    write_obj(tmp_path)
    (tmp_path / "m.mtl").write_text(
        "newmtl plain\nKd 1 0 0\nKa 1 0 0\nnewmtl textured\nKd 1 1 1\nKa 1 1 1\nmap_Kd stripes.png\n"
    )
    write_image(tmp_path / "halves.png", GREEN[::-1], BLUE[::-1])
    (tmp_path / "m.dae").write_text(COLLADA.format(texture="halves.png"))
    # the COLLADA node lifts its quad 2 m along the quad's normal: 2 m nearer the camera
    dae_pose = FACE_ON.format(y=-1.05).replace(f"{DISTANCE} ", f"{DISTANCE + 2} ", 1)
    visuals = (
        f'<visual name="obj"><pose>{FACE_ON.format(y=0.05)}</pose><geometry><mesh><uri>m.obj</uri></mesh></geometry></visual>'
        f'<visual name="dae"><pose>{dae_pose}</pose><geometry><mesh><uri>m.dae</uri></mesh></geometry></visual>'
    )
    (tmp_path / "world.sdf").write_text(
        '<?xml version="1.0"?><sdf version="1.9"><world name="w"><model name="thing"><static>true</static>'
        f'<link name="base">{visuals}</link></model></world></sdf>'
    )
    description = load_world(tmp_path / "world.sdf")
    physics = Physics(description)
    try:
        physics.add_model(description.models[0])
        body = scene_body(physics, "thing")
    finally:
        physics.close()
    with drawing([body], replace(DARK, ambient=(1.0, 1.0, 1.0)), camera()) as draw:
        image = draw(((0.0, 0.0, 0.0), AHEAD))["color"]
    dae_red = (255, 0, 51)  # the COLLADA red's <emission> adds 0.2 blue
    for left, red in ((0.05, RED), (-1.05, dae_red)):  # each quad spans y left .. left + 1, z −0.5 .. 0.5
        for (y, z), colour in {(0.7, -0.3): GREEN, (0.8, 0.2): BLUE, (0.3, 0.3): red}.items():
            row, column = pixel(left + y, z)
            assert np.abs(image[row, column].astype(int) - colour).max() <= 2, (left, y, z, image[row, column])
