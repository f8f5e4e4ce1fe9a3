"""COLLADA skeletons and animations, read as Gazebo's actors use them (gz-common's ColladaLoader).

- A skin's skeleton: the joint nodes of `<library_visual_scenes>` (the subtrees its
  `<instance_controller><skeleton>` names, else every `type="JOINT"` node) with their rest
  transforms (`<matrix>`, `<translate>`, `<rotate>`, `<scale>` in order), and each
  `<library_controllers>` `<skin>`: its `<bind_shape_matrix>`, its joints (by `sid`, else `name`,
  else `id`), their inverse bind matrices and each vertex's weights. The skinned geometry
  (`<triangles>` or `<polylist>`) is read as triangles in skin space (the bind shape matrix
  applied), one `SkinPart` per material, with the material's diffuse colour or texture.
- An animation file's clip: `<library_animations>` channels that target a joint node's transform
  (`<matrix>` as float4x4 keys, or its `<translate>`/`<rotate>` by their sid), sampled at every
  key time of the file; a joint without a channel keeps its rest transform.
- `<asset><unit meter>`: each file's lengths (vertices, joint and bind translations, a clip's
  translations) in metres, as gz-common's ColladaLoader scales a mesh, its skeleton and its
  animations by it. Its `<up_axis>` is not applied: ColladaLoader does not either.

Matrices are COLLADA's: row-major text, column vectors. A file that cannot be read raises
`SkeletonError` saying why; the caller warns and draws the skin as it stands.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import numpy.typing as npt

from simbot.transform import axis_rotations, matmul

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
INFLUENCES = 4
"""Weights kept per vertex (the largest, renormalised): what linear blend skinning takes."""


class SkeletonError(ValueError):
    """A skeleton or an animation that cannot be used, and why."""


@dataclass(frozen=True, eq=False)
class SkinPart:
    """Triangles of one material of a skinned geometry, in skin space; three rows a triangle."""

    material: str
    colour: tuple[float, float, float, float]
    texture: Path | None
    positions: F64
    uvs: F64
    joints: I64
    """N×INFLUENCES skeleton joint indices."""
    weights: F64
    """N×INFLUENCES, each row summing to 1."""


@dataclass(frozen=True, eq=False)
class Skeleton:
    """A skin's joints (parents before children), their rest transforms and inverse bind matrices."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    """Each joint's parent index, -1 for a root."""
    rest: F64
    """J×4×4 local transforms (a root's: in the visual scene's frame)."""
    inverse_bind: F64
    """J×4×4; identity for a joint no skin binds."""
    parts: tuple[SkinPart, ...]

    def index(self, name: str) -> int:
        return self.names.index(name)


@dataclass(frozen=True, eq=False)
class Clip:
    """An animation's keyframes: each joint's local transform at each key time."""

    times: F64
    """K key times, seconds, from 0."""
    locals: F64
    """K×J×4×4."""

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def scaled(self, scale: float) -> Clip:
        """The clip with every joint's translation times `scale` (an `<animation>`'s `<scale>`)."""
        if scale == 1.0:
            return self
        locals_ = self.locals.copy()
        locals_[..., :3, 3] *= scale
        return Clip(self.times, locals_)

    @property
    def x_displacement(self) -> float:
        """How far the root moves along x over the clip (gz-common's XDisplacement): a cycle's stride."""
        return float(self.locals[-1, 0, 0, 3] - self.locals[0, 0, 0, 3])


def read_skeleton(path: Path) -> Skeleton:
    """The skin's skeleton and skinned triangles; SkeletonError when it has none or it cannot be read."""
    root = _parse(path)
    nodes = _joint_nodes(root)
    if not nodes:
        raise SkeletonError("no skeleton (no <instance_controller> with joint nodes)")
    names, parents, rest = _hierarchy(nodes)
    lookup = _node_names(nodes)
    inverse_bind = np.tile(np.eye(4), (len(names), 1, 1))
    parts: list[SkinPart] = []
    for instance in root.iter("instance_controller"):
        controller = _by_id(root, instance.get("url", ""))
        skin = controller.find("skin") if controller is not None else None
        if skin is None:
            raise SkeletonError(f"<instance_controller url={instance.get('url')!r}>: no <skin> of that id")
        parts += _skin_parts(path, root, skin, instance, lookup, inverse_bind)
    if not parts:
        raise SkeletonError("no skinned triangles")
    meter = _meter(root)
    rest[:, :3, 3] *= meter
    inverse_bind[:, :3, 3] *= meter
    parts = [replace(part, positions=part.positions * meter) for part in parts]
    return Skeleton(tuple(names), tuple(parents), rest, inverse_bind, tuple(parts))


def read_clip(path: Path, skeleton: Skeleton) -> Clip:
    """The file's animation of `skeleton`; SkeletonError naming a channel's joint the skeleton lacks."""
    root = _parse(path)
    channels: dict[int, list[tuple[str, F64, F64]]] = {}
    ids = {node.get("id"): node for node in root.iter("node")}
    for animation in root.iter("animation"):
        for channel in animation.findall("channel"):
            target = channel.get("target", "")
            node_id, _, element = target.partition("/")
            node = ids.get(node_id)
            name = _joint_name(node) if node is not None else node_id
            joint = next((i for i, n in enumerate(skeleton.names) if n in (name, node_id)), None)
            if joint is None:
                raise SkeletonError(f"<channel target={target!r}>: the skin has no joint {name!r}")
            times, values = _sampler(animation, channel.get("source", ""))
            channels.setdefault(joint, []).append((element, times, values))
    if not channels:
        raise SkeletonError("no <animation> channel")
    times = np.unique(np.concatenate([t for chans in channels.values() for _, t, _ in chans]))
    times = times - times[0]
    locals_ = np.tile(skeleton.rest, (len(times), 1, 1, 1))
    meter = _meter(root)
    for joint, chans in channels.items():
        locals_[:, joint] = _animated(ids, skeleton.names[joint], chans, times)
        locals_[:, joint, :3, 3] *= meter
    return Clip(times, locals_)


# --- the document


def _parse(path: Path) -> ET.Element:
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise SkeletonError(f"cannot be read ({exc})") from None
    for element in root.iter():
        element.tag = element.tag.rpartition("}")[2]
    return root


def _meter(root: ET.Element) -> float:
    """Metres per unit of the file's lengths (`<asset><unit meter>`, 1 without one)."""
    unit = root.find("asset/unit")
    text = unit.get("meter", "1") if unit is not None else "1"
    try:
        meter = float(text)
    except ValueError:
        meter = math.nan
    if not (math.isfinite(meter) and meter > 0.0):
        raise SkeletonError(f"<unit meter={text!r}>: not a positive number")
    return meter


def _by_id(root: ET.Element, url: str) -> ET.Element | None:
    wanted = url.lstrip("#")
    return next((e for e in root.iter() if e.get("id") == wanted), None)


def _floats(element: ET.Element | None) -> F64:
    return np.array([] if element is None or not element.text else element.text.split(), dtype=np.float64)


def _source(root: ET.Element, url: str) -> tuple[F64 | list[str], int]:
    """A `<source>`'s values (numbers, or names) and its accessor's stride."""
    source = _by_id(root, url)
    if source is None:
        raise SkeletonError(f"no <source id={url!r}>")
    accessor = source.find("technique_common/accessor")
    stride = int(accessor.get("stride", "1")) if accessor is not None else 1
    names = source.find("Name_array")
    names = names if names is not None else source.find("IDREF_array")
    if names is not None:
        return (names.text or "").split(), stride
    return _floats(source.find("float_array")), stride


def _matrix(values: F64) -> F64:
    return values.reshape(4, 4)


# --- the skeleton


def _joint_nodes(root: ET.Element) -> list[ET.Element]:
    """The skeletons' root nodes: those the instance controllers name, else every top JOINT node."""
    named = [_by_id(root, s.text or "") for s in root.iter("skeleton")]
    found = [node for node in named if node is not None]
    if found:
        return list(dict.fromkeys(found))
    joints = [node for node in root.iter("node") if node.get("type") == "JOINT"]
    inner = {id(child) for node in joints for child in node.iter("node") if child is not node}
    return [node for node in joints if id(node) not in inner]


def _hierarchy(tops: list[ET.Element]) -> tuple[list[str], list[int], F64]:
    names: list[str] = []
    parents: list[int] = []
    rest: list[F64] = []

    def visit(node: ET.Element, parent: int) -> None:
        index = len(names)
        names.append(_joint_name(node))
        parents.append(parent)
        rest.append(_node_transform(node))
        for child in node.findall("node"):
            visit(child, index)

    for top in tops:
        visit(top, -1)
    if len(set(names)) != len(names):
        raise SkeletonError("two joints share a name")
    return names, parents, np.array(rest)


def _joint_name(node: ET.Element) -> str:
    return node.get("sid") or node.get("name") or node.get("id") or ""


def _node_names(tops: list[ET.Element]) -> dict[str, int]:
    """Every way a skin may name a joint (sid, name, id) → its index, in `_hierarchy`'s order."""
    lookup: dict[str, int] = {}
    for index, node in enumerate(n for top in tops for n in top.iter("node")):
        for key in (node.get("id"), node.get("name"), node.get("sid")):
            if key:
                lookup.setdefault(key, index)
    return lookup


def _node_transform(node: ET.Element) -> F64:
    """A node's transform elements composed in order."""
    out = np.eye(4)
    for element in node:
        out = matmul(out, _element_matrix(element.tag, _floats(element)))
    return out


def _element_matrix(tag: str, values: F64) -> F64:
    out = np.eye(4)
    if tag == "matrix" and len(values) == 16:
        return _matrix(values)
    if tag == "translate" and len(values) == 3:
        out[:3, 3] = values
    elif tag == "scale" and len(values) == 3:
        out[:3, :3] = np.diag(values)
    elif tag == "rotate" and len(values) == 4:
        out[:3, :3] = axis_rotations(values[:3], math.radians(float(values[3])))[0]
    return out


# --- the skins


def _skin_parts(
    path: Path, root: ET.Element, skin: ET.Element, instance: ET.Element, lookup: dict[str, int], inverse_bind: F64
) -> list[SkinPart]:
    bind_shape = _floats(skin.find("bind_shape_matrix"))
    bind_shape = _matrix(bind_shape) if len(bind_shape) == 16 else np.eye(4)
    joints = skin.find("joints")
    inputs = {i.get("semantic"): i.get("source", "") for i in (joints if joints is not None else [])}
    names, _ = _source(root, inputs.get("JOINT", ""))
    matrices, _ = _source(root, inputs.get("INV_BIND_MATRIX", ""))
    missing = [name for name in names if name not in lookup]
    if missing:
        raise SkeletonError(f"<skin source={skin.get('source')!r}>: joint {missing[0]!r} is not a node of the skeleton")
    order = np.array([lookup[str(name)] for name in names], dtype=np.int64)
    inverse_bind[order] = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
    influences = _weights(root, skin, order)
    geometry = _by_id(root, skin.get("source", ""))
    if geometry is None:
        raise SkeletonError(f"<skin source={skin.get('source')!r}>: no geometry of that id")
    materials = _bound_materials(instance)
    return [
        _part(path, root, primitive, bind_shape, influences, materials)
        for primitive in geometry.iter()
        if primitive.tag in ("triangles", "polylist")
    ]


def _weights(root: ET.Element, skin: ET.Element, order: I64) -> tuple[I64, F64]:
    """Each vertex's INFLUENCES largest weights and their skeleton joints."""
    vertex_weights = skin.find("vertex_weights")
    if vertex_weights is None:
        raise SkeletonError(f"<skin source={skin.get('source')!r}>: no <vertex_weights>")
    inputs = {i.get("semantic"): i for i in vertex_weights.findall("input")}
    weights, _ = _source(root, inputs["WEIGHT"].get("source", "")) if "WEIGHT" in inputs else (np.ones(1), 1)
    joint_offset, weight_offset = (int(inputs[s].get("offset", "0")) for s in ("JOINT", "WEIGHT"))
    counts = _floats(vertex_weights.find("vcount")).astype(np.int64)
    pairs = _floats(vertex_weights.find("v")).astype(np.int64).reshape(-1, len(inputs))
    joints = np.zeros((len(counts), INFLUENCES), dtype=np.int64)
    values = np.zeros((len(counts), INFLUENCES))
    start = 0
    for vertex, count in enumerate(counts):
        rows = pairs[start : start + count]
        start += count
        ranked = sorted(
            ((float(np.asarray(weights)[w]), int(order[j])) for j, w in rows[:, [joint_offset, weight_offset]]),
            reverse=True,
        )
        for k, (weight, joint) in enumerate(ranked[:INFLUENCES]):
            joints[vertex, k], values[vertex, k] = joint, weight
    total = values.sum(axis=1, keepdims=True)
    if np.any(total <= 0.0):
        raise SkeletonError(f"<skin source={skin.get('source')!r}>: a vertex has no weight")
    return joints, values / total


def _bound_materials(instance: ET.Element) -> dict[str, str]:
    return {m.get("symbol", ""): m.get("target", "") for m in instance.iter("instance_material")}


def _part(
    path: Path,
    root: ET.Element,
    primitive: ET.Element,
    bind_shape: F64,
    influences: tuple[I64, F64],
    materials: dict[str, str],
) -> SkinPart:
    inputs = primitive.findall("input")
    stride = max(int(i.get("offset", "0")) for i in inputs) + 1
    indices = _floats(primitive.find("p")).astype(np.int64).reshape(-1, stride)
    if primitive.tag == "polylist":
        indices = indices[_fan(_floats(primitive.find("vcount")).astype(np.int64))]
    offsets = {i.get("semantic"): int(i.get("offset", "0")) for i in inputs}
    vertex = indices[:, offsets["VERTEX"]]
    positions = _positions(root, next(i for i in inputs if i.get("semantic") == "VERTEX").get("source", ""))
    placed = matmul(positions, bind_shape[:3, :3].T) + bind_shape[:3, 3]
    uvs = np.zeros((len(vertex), 2))
    if "TEXCOORD" in offsets:
        values, width = _source(root, next(i for i in inputs if i.get("semantic") == "TEXCOORD").get("source", ""))
        uvs = np.asarray(values, dtype=np.float64).reshape(-1, width)[indices[:, offsets["TEXCOORD"]], :2]
    joints, weights = influences
    symbol = primitive.get("material", "")
    colour, texture = _material(path, root, materials.get(symbol, symbol))
    return SkinPart(symbol, colour, texture, placed[vertex], uvs, joints[vertex], weights[vertex])


def _fan(counts: I64) -> I64:
    """Rows of a polylist's polygons, as triangles (a fan from each polygon's first corner)."""
    rows, start = [], 0
    for count in counts:
        rows += [index for k in range(1, count - 1) for index in (start, start + k, start + k + 1)]
        start += count
    return np.array(rows, dtype=np.int64)


def _positions(root: ET.Element, url: str) -> F64:
    vertices = _by_id(root, url)
    position = (
        next((i for i in vertices.findall("input") if i.get("semantic") == "POSITION"), None)
        if vertices is not None
        else None
    )
    if position is None:
        raise SkeletonError(f"<vertices id={url!r}>: no POSITION input")
    values, _ = _source(root, position.get("source", ""))
    return np.asarray(values, dtype=np.float64).reshape(-1, 3)


def _material(path: Path, root: ET.Element, url: str) -> tuple[tuple[float, float, float, float], Path | None]:
    """A material's diffuse colour, or its texture's file (white then): Gazebo's look of a skin."""
    material = _by_id(root, url)
    instance = material.find("instance_effect") if material is not None else None
    effect = _by_id(root, instance.get("url", "")) if instance is not None else None
    diffuse = next(effect.iter("diffuse"), None) if effect is not None else None
    if diffuse is None:
        return (1.0, 1.0, 1.0, 1.0), None
    colour = _floats(diffuse.find("color"))
    if len(colour) >= 3:
        return (
            float(colour[0]),
            float(colour[1]),
            float(colour[2]),
            float(colour[3]) if len(colour) > 3 else 1.0,
        ), None
    return (1.0, 1.0, 1.0, 1.0), _texture(path, root, effect, diffuse)


def _texture(path: Path, root: ET.Element, effect: ET.Element | None, diffuse: ET.Element) -> Path | None:
    texture = diffuse.find("texture")
    if texture is None or effect is None:
        return None
    params = {p.get("sid"): p for p in effect.iter("newparam")}
    sampler = params.get(texture.get("texture"))
    surface_id = sampler.findtext("sampler2D/source") if sampler is not None else None
    surface = params.get(surface_id) if surface_id else None
    image_id = surface.findtext("surface/init_from") if surface is not None else texture.get("texture")
    image = _by_id(root, image_id or "")
    name = image.findtext("init_from") if image is not None else None
    return None if not name else path.parent / unquote(name.strip().removeprefix("file://"))


# --- the animations


def _sampler(animation: ET.Element, url: str) -> tuple[F64, F64]:
    sampler = next((s for s in animation.iter("sampler") if s.get("id") == url.lstrip("#")), None)
    if sampler is None:
        raise SkeletonError(f"<channel source={url!r}>: no <sampler> of that id")
    inputs = {i.get("semantic"): i.get("source", "") for i in sampler.findall("input")}
    times, _ = _source(animation, inputs.get("INPUT", ""))
    values, _ = _source(animation, inputs.get("OUTPUT", ""))
    times = np.asarray(times, dtype=np.float64)
    if not len(times) or np.any(np.diff(times) <= 0.0):
        raise SkeletonError(f"<sampler id={url.lstrip('#')!r}>: its key times are not increasing")
    return times, np.asarray(values, dtype=np.float64).reshape(len(times), -1)


def _animated(ids: dict[str | None, ET.Element], joint: str, chans: list[tuple[str, F64, F64]], times: F64) -> F64:
    """A joint's local transform at `times`: its matrix channel, or its node's elements with the
    animated ones replaced."""
    node = next(n for n in ids.values() if _joint_name(n) == joint or n.get("id") == joint)
    out = np.empty((len(times), 4, 4))
    for k, time in enumerate(times):
        matrix = np.eye(4)
        for element in node:
            values = _floats(element)
            for target, keys, samples in chans:
                sid, _, part = target.partition(".")
                if sid == element.get("sid"):
                    values = _at(keys, samples, time, values, part)
            matrix = matmul(matrix, _element_matrix(element.tag, values))
        out[k] = matrix
    return out


def _at(keys: F64, samples: F64, time: float, values: F64, part: str) -> F64:
    """A channel's value at `time` (linear between keys, held beyond them), into the element's values."""
    start = keys[0]
    sample = np.array([np.interp(time + start, keys, samples[:, c]) for c in range(samples.shape[1])])
    if not part:
        return sample
    out = values.copy()
    out[{"X": 0, "Y": 1, "Z": 2, "ANGLE": 3}.get(part.upper(), 3)] = sample[0]
    return out
