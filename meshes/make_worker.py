#!/usr/bin/env python3
"""Write simbot's own human figure, a warehouse worker, as a COLLADA skin for `<actor>`s.

Gazebo's actor worlds take their skins from Fuel (walk.dae and friends), which simbot does not
download; this is the project's own: a standing adult 1.84 m tall in the proportions of Gazebo's
stock skins, its origin at the pelvis (so an actor's `<pose>` stands it on the floor at z 1.0, as
gz-sim's worlds place theirs), +x forward, z up, in metres. Boots, trousers, a high-visibility
yellow vest over dark sleeves, a face and a white hard hat: one material each, so a camera tells
a person from the orange racks and the grey floor. It is a bind pose only (no skeleton): simbot
draws skins unanimated.

Every part is a trimesh primitive (boxes, capped cylinders, spheres) placed on the figure; the file
is written by hand (COLLADA 1.4.1, one geometry per material), deterministic: the same bytes on
every run.

    python3 meshes/make_worker.py [--out worlds/models/worker/meshes/worker.dae]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import trimesh

OUT = Path(__file__).resolve().parents[1] / "worlds" / "models" / "worker" / "meshes" / "worker.dae"
COLOURS = {
    "boots": (0.12, 0.10, 0.08),
    "trousers": (0.16, 0.20, 0.30),
    "vest": (0.93, 0.90, 0.10),
    "sleeves": (0.20, 0.22, 0.25),
    "skin": (0.80, 0.62, 0.50),
    "hat": (0.95, 0.95, 0.93),
}


def _at(mesh: trimesh.Trimesh, x: float, y: float, z: float) -> trimesh.Trimesh:
    mesh.apply_translation((x, y, z))
    return mesh


def _limb(radius: float, bottom: float, top: float, y: float, x: float = 0.0) -> trimesh.Trimesh:
    """An upright capped cylinder from z `bottom` to `top`."""
    return _at(trimesh.creation.cylinder(radius=radius, height=top - bottom, sections=16), x, y, (top + bottom) / 2)


def parts() -> dict[str, list[trimesh.Trimesh]]:
    """The figure's pieces by material, pelvis at the origin, feet at z −1.0."""
    return {
        "boots": [_at(trimesh.creation.box((0.28, 0.11, 0.08)), 0.04, y, -0.96) for y in (-0.1, 0.1)],
        "trousers": [_limb(0.075, -0.92, 0.02, y) for y in (-0.1, 0.1)]
        + [_at(trimesh.creation.box((0.22, 0.36, 0.14)), 0, 0, 0.0)],
        "vest": [_at(trimesh.creation.box((0.24, 0.40, 0.54)), 0, 0, 0.29)],
        "sleeves": [_limb(0.05, 0.02, 0.54, y) for y in (-0.25, 0.25)],
        "skin": [_limb(0.05, 0.54, 0.62, 0.0), _at(trimesh.creation.icosphere(subdivisions=2, radius=0.1), 0, 0, 0.68)]
        + [_at(trimesh.creation.icosphere(subdivisions=1, radius=0.05), 0, y, 0.0) for y in (-0.25, 0.25)],
        "hat": [_limb(0.12, 0.73, 0.75, 0.0), _at(trimesh.creation.icosphere(subdivisions=2, radius=0.1), 0, 0, 0.74)],
    }


def _numbers(values: np.ndarray) -> str:
    return " ".join(f"{v:.5g}" for v in values.ravel())


def collada(pieces: dict[str, list[trimesh.Trimesh]]) -> str:
    """COLLADA 1.4.1 text: per material an effect, a material, a geometry and a node instancing it."""
    effects, materials, geometries, nodes = [], [], [], []
    for name, meshes in pieces.items():
        mesh = trimesh.util.concatenate(meshes)
        r, g, b = COLOURS[name]
        effects.append(
            f'<effect id="{name}-fx"><profile_COMMON><technique sid="common"><lambert>'
            f"<diffuse><color>{r} {g} {b} 1</color></diffuse></lambert></technique></profile_COMMON></effect>"
        )
        materials.append(f'<material id="{name}-mat" name="{name}"><instance_effect url="#{name}-fx"/></material>')
        count = len(mesh.vertices)
        geometries.append(
            f'<geometry id="{name}-geo" name="{name}"><mesh>'
            f'<source id="{name}-pos"><float_array id="{name}-pos-array" count="{count * 3}">'
            f"{_numbers(np.asarray(mesh.vertices))}</float_array>"
            f'<technique_common><accessor source="#{name}-pos-array" count="{count}" stride="3">'
            '<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>'
            "</accessor></technique_common></source>"
            f'<vertices id="{name}-vtx"><input semantic="POSITION" source="#{name}-pos"/></vertices>'
            f'<triangles material="{name}" count="{len(mesh.faces)}">'
            f'<input semantic="VERTEX" source="#{name}-vtx" offset="0"/>'
            f"<p>{' '.join(str(int(i)) for i in np.asarray(mesh.faces).ravel())}</p></triangles>"
            "</mesh></geometry>"
        )
        nodes.append(
            f'<node id="{name}" name="{escape(name)}"><instance_geometry url="#{name}-geo"><bind_material>'
            f'<technique_common><instance_material symbol="{name}" target="#{name}-mat"/></technique_common>'
            "</bind_material></instance_geometry></node>"
        )
    return "\n".join(
        [
            '<?xml version="1.0" encoding="utf-8"?>',
            '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">',
            "<asset><contributor><authoring_tool>simbot meshes/make_worker.py</authoring_tool></contributor>"
            '<unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>',
            f"<library_effects>{''.join(effects)}</library_effects>",
            f"<library_materials>{''.join(materials)}</library_materials>",
            f"<library_geometries>{''.join(geometries)}</library_geometries>",
            f'<library_visual_scenes><visual_scene id="worker" name="worker">{"".join(nodes)}</visual_scene>'
            "</library_visual_scenes>",
            '<scene><instance_visual_scene url="#worker"/></scene>',
            "</COLLADA>",
            "",
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(collada(parts()))
    print(args.out)


if __name__ == "__main__":
    main()
