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


JOINTS = {
    "pelvis": (None, (0.0, 0.0, 0.0)),
    "spine": ("pelvis", (0.0, 0.0, 0.02)),
    "neck": ("spine", (0.0, 0.0, 0.54)),
    **{
        f"{bone}_{side}": (parent if parent == "pelvis" or parent == "spine" else f"{parent}_{side}", (0.0, y, z))
        for side, sign in (("l", 1.0), ("r", -1.0))
        for bone, parent, y, z in (
            ("thigh", "pelvis", 0.1 * sign, 0.0),
            ("shin", "thigh", 0.1 * sign, -0.46),
            ("foot", "shin", 0.1 * sign, -0.92),
            ("upperarm", "spine", 0.25 * sign, 0.54),
            ("forearm", "upperarm", 0.25 * sign, 0.28),
        )
    },
}
"""The skeleton: each joint's parent and its position on the figure (pelvis at the origin), +y left."""
CYCLE_S = 1.1
"""A walk cycle: two steps."""
STRIDE_M = 1.4
"""How far the pelvis goes in a cycle (the clip's x displacement, what `<interpolate_x>` ties to the distance walked)."""
LEG_M = 0.92
"""Hip to ankle."""
SWING = float(np.arcsin(STRIDE_M / 4 / LEG_M))
"""The thigh's swing each way: the feet a quarter stride ahead and behind at double support."""
KNEE_BEND = 1.0
"""Radians the swinging leg's knee bends at mid-swing."""
ARM_SWING = 0.5
"""An arm's swing over its opposite leg's."""
KEYS = 23
"""Keys of the clip (every 50 ms, both ends)."""

Piece = tuple[trimesh.Trimesh, str, str | None, str | None]
"""A mesh, its bone, and the bones its top and bottom rings are shared with half and half (a smooth hip or
knee), or None."""


def _rigid(mesh: trimesh.Trimesh, bone: str) -> Piece:
    return mesh, bone, None, None


def parts() -> dict[str, list[Piece]]:
    """The figure's pieces by material and bone, pelvis at the origin, feet at z −1.0."""
    sides = (("l", 1.0), ("r", -1.0))
    box, sphere = trimesh.creation.box, trimesh.creation.icosphere
    return {
        "boots": [_rigid(_at(box((0.28, 0.11, 0.08)), 0.04, 0.1 * s, -0.96), f"foot_{n}") for n, s in sides],
        "trousers": [(_limb(0.075, -0.46, 0.02, 0.1 * s), f"thigh_{n}", "pelvis", f"shin_{n}") for n, s in sides]
        + [(_limb(0.075, -0.92, -0.46, 0.1 * s), f"shin_{n}", f"thigh_{n}", None) for n, s in sides]
        + [_rigid(_at(box((0.22, 0.36, 0.14)), 0, 0, 0.0), "pelvis")],
        "vest": [_rigid(_at(box((0.24, 0.40, 0.54)), 0, 0, 0.29), "spine")],
        "sleeves": [_rigid(_limb(0.05, 0.28, 0.54, 0.25 * s), f"upperarm_{n}") for n, s in sides]
        + [_rigid(_limb(0.05, 0.02, 0.28, 0.25 * s), f"forearm_{n}") for n, s in sides],
        "skin": [
            _rigid(_limb(0.05, 0.54, 0.62, 0.0), "neck"),
            _rigid(_at(sphere(subdivisions=2, radius=0.1), 0, 0, 0.68), "neck"),
        ]
        + [_rigid(_at(sphere(subdivisions=1, radius=0.05), 0, 0.25 * s, 0.0), f"forearm_{n}") for n, s in sides],
        "hat": [
            _rigid(_limb(0.12, 0.73, 0.75, 0.0), "neck"),
            _rigid(_at(sphere(subdivisions=2, radius=0.1), 0, 0, 0.74), "neck"),
        ],
    }


def _weights(piece: Piece) -> list[list[tuple[int, float]]]:
    """Each vertex's (joint index, weight)s."""
    mesh, bone, top, bottom = piece
    names = list(JOINTS)
    z = np.asarray(mesh.vertices)[:, 2]
    out = []
    for height in z:
        partner = top if height == z.max() else bottom if height == z.min() else None
        out.append(
            [(names.index(bone), 1.0)] if partner is None else [(names.index(bone), 0.5), (names.index(partner), 0.5)]
        )
    return out


def _rest(name: str) -> np.ndarray:
    """A joint's rest transform relative to its parent: a translation."""
    parent, at = JOINTS[name]
    out = np.eye(4)
    out[:3, 3] = np.subtract(at, JOINTS[parent][1]) if parent else at
    return out


def _turn_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s, 0.0], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, 0.0], [0.0, 0.0, 0.0, 1.0]])


def walk(phase: float) -> dict[str, np.ndarray]:
    """The animated joints' local transforms at `phase` (0..1) of the cycle: at 0 the left foot a quarter
    stride ahead and the right one behind, both on the floor; each leg's knee bends as it swings
    forward; the pelvis dips at double support (the legs straight) and moves a stride along x."""
    swing = SWING * np.cos(2 * np.pi * phase)  # the left thigh forward of vertical
    out = {}
    for side, thigh, swinging in (("l", swing, phase >= 0.5), ("r", -swing, phase < 0.5)):
        knee = KNEE_BEND * abs(np.sin(2 * np.pi * phase)) if swinging else 0.0
        out[f"thigh_{side}"] = _rest(f"thigh_{side}") @ _turn_y(-thigh)
        out[f"shin_{side}"] = _rest(f"shin_{side}") @ _turn_y(knee)
        out[f"upperarm_{side}"] = _rest(f"upperarm_{side}") @ _turn_y(ARM_SWING * thigh)
    pelvis = _rest("pelvis")
    pelvis[0, 3] = STRIDE_M * phase
    pelvis[2, 3] = -LEG_M * (1.0 - np.cos(swing))
    out["pelvis"] = pelvis
    return out


def _numbers(values: np.ndarray) -> str:
    return " ".join(f"{v:.5g}" for v in values.ravel())


def _source(ident: str, values: str, count: int, stride: int, param: str, kind: str, array: str = "float_array") -> str:
    """A COLLADA `<source>` of `count` items `stride` values each."""
    return (
        f'<source id="{ident}"><{array} id="{ident}-array" count="{count * stride}">{values}</{array}>'
        f'<technique_common><accessor source="#{ident}-array" count="{count}" stride="{stride}">'
        f'<param name="{param}" type="{kind}"/></accessor></technique_common></source>'
    )


def _skeleton_nodes(name: str | None = None) -> str:
    """The joint nodes under `name` (the roots for None), each with its rest matrix."""
    return "".join(
        f'<node id="{joint}" name="{joint}" sid="{joint}" type="JOINT">'
        f'<matrix sid="transform">{_numbers(_rest(joint))}</matrix>{_skeleton_nodes(joint)}</node>'
        for joint, (parent, _) in JOINTS.items()
        if parent == name
    )


def _controller(name: str, count: int, weights: list[list[tuple[int, float]]]) -> str:
    """A skin of geometry `name` on the whole skeleton: inverse binds (the rest positions negated) and weights."""
    binds = []
    for _, at in JOINTS.values():
        inverse = np.eye(4)
        inverse[:3, 3] = np.negative(at)
        binds.append(inverse)
    values = sorted({w for vertex in weights for _, w in vertex})
    pairs = " ".join(f"{j} {values.index(w)}" for vertex in weights for j, w in vertex)
    return (
        f'<controller id="{name}-skin"><skin source="#{name}-geo">'
        f"<bind_shape_matrix>{_numbers(np.eye(4))}</bind_shape_matrix>"
        + _source(f"{name}-joints", " ".join(JOINTS), len(JOINTS), 1, "JOINT", "name", "Name_array")
        + _source(f"{name}-binds", _numbers(np.array(binds)), len(JOINTS), 16, "TRANSFORM", "float4x4")
        + _source(f"{name}-weights", _numbers(np.array(values)), len(values), 1, "WEIGHT", "float")
        + f'<joints><input semantic="JOINT" source="#{name}-joints"/>'
        f'<input semantic="INV_BIND_MATRIX" source="#{name}-binds"/></joints>'
        f'<vertex_weights count="{count}"><input semantic="JOINT" source="#{name}-joints" offset="0"/>'
        f'<input semantic="WEIGHT" source="#{name}-weights" offset="1"/>'
        f"<vcount>{' '.join(str(len(v)) for v in weights)}</vcount><v>{pairs}</v></vertex_weights>"
        "</skin></controller>"
    )


def _document(libraries: list[str]) -> str:
    return "\n".join(
        [
            '<?xml version="1.0" encoding="utf-8"?>',
            '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">',
            "<asset><contributor><authoring_tool>simbot meshes/make_worker.py</authoring_tool></contributor>"
            '<unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>',
            *libraries,
            '<scene><instance_visual_scene url="#worker"/></scene>',
            "</COLLADA>",
            "",
        ]
    )


def collada(pieces: dict[str, list[Piece]]) -> str:
    """COLLADA 1.4.1 text: per material an effect, a material, a geometry, its skin on the skeleton
    and a node instancing it; the skeleton's joint nodes."""
    effects, materials, geometries, controllers, nodes = [], [], [], [], []
    for name, group in pieces.items():
        mesh = trimesh.util.concatenate([piece[0] for piece in group])
        weights = [w for piece in group for w in _weights(piece)]
        r, g, b = COLOURS[name]
        effects.append(
            f'<effect id="{name}-fx"><profile_COMMON><technique sid="common"><lambert>'
            f"<diffuse><color>{r} {g} {b} 1</color></diffuse></lambert></technique></profile_COMMON></effect>"
        )
        materials.append(f'<material id="{name}-mat" name="{name}"><instance_effect url="#{name}-fx"/></material>')
        count = len(mesh.vertices)
        geometries.append(
            f'<geometry id="{name}-geo" name="{name}"><mesh>'
            + _source(f"{name}-pos", _numbers(np.asarray(mesh.vertices)), count, 3, "X", "float")
            + f'<vertices id="{name}-vtx"><input semantic="POSITION" source="#{name}-pos"/></vertices>'
            f'<triangles material="{name}" count="{len(mesh.faces)}">'
            f'<input semantic="VERTEX" source="#{name}-vtx" offset="0"/>'
            f"<p>{' '.join(str(int(i)) for i in np.asarray(mesh.faces).ravel())}</p></triangles>"
            "</mesh></geometry>"
        )
        controllers.append(_controller(name, count, weights))
        nodes.append(
            f'<node id="{name}" name="{escape(name)}"><instance_controller url="#{name}-skin">'
            "<skeleton>#pelvis</skeleton><bind_material>"
            f'<technique_common><instance_material symbol="{name}" target="#{name}-mat"/></technique_common>'
            "</bind_material></instance_controller></node>"
        )
    return _document(
        [
            f"<library_effects>{''.join(effects)}</library_effects>",
            f"<library_materials>{''.join(materials)}</library_materials>",
            f"<library_geometries>{''.join(geometries)}</library_geometries>",
            f"<library_controllers>{''.join(controllers)}</library_controllers>",
            f'<library_visual_scenes><visual_scene id="worker" name="worker">{_skeleton_nodes()}{"".join(nodes)}'
            "</visual_scene></library_visual_scenes>",
        ]
    )


def walk_collada() -> str:
    """The walk cycle: a matrix channel per animated joint, KEYS keys over CYCLE_S, and the skeleton it moves."""
    phases = np.linspace(0.0, 1.0, KEYS)
    poses = [walk(float(p)) for p in phases]
    times = _numbers(phases * CYCLE_S)
    animations = []
    for joint in poses[0]:
        matrices = _numbers(np.array([pose[joint] for pose in poses]))
        animations.append(
            f'<animation id="{joint}-walk">'
            + _source(f"{joint}-walk-time", times, KEYS, 1, "TIME", "float")
            + _source(f"{joint}-walk-pose", matrices, KEYS, 16, "TRANSFORM", "float4x4")
            + _source(f"{joint}-walk-how", " ".join(["LINEAR"] * KEYS), KEYS, 1, "INTERPOLATION", "name", "Name_array")
            + f'<sampler id="{joint}-walk-sampler"><input semantic="INPUT" source="#{joint}-walk-time"/>'
            f'<input semantic="OUTPUT" source="#{joint}-walk-pose"/>'
            f'<input semantic="INTERPOLATION" source="#{joint}-walk-how"/></sampler>'
            f'<channel source="#{joint}-walk-sampler" target="{joint}/transform"/></animation>'
        )
    return _document(
        [
            f"<library_animations>{''.join(animations)}</library_animations>",
            f'<library_visual_scenes><visual_scene id="worker" name="worker">{_skeleton_nodes()}'
            "</visual_scene></library_visual_scenes>",
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="the skin; walk.dae is written beside it")
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(collada(parts()))
    (args.out.parent / "walk.dae").write_text(walk_collada())
    print(args.out)


if __name__ == "__main__":
    main()
