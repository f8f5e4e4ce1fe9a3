"""BVH motion files as an actor's `<animation>`, read as Gazebo plays them (gz-common's BVHLoader).

gz-sim gives an `<animation>` whose `<filename>` ends in `.bvh` to gz-common's BVHLoader, so a
BVH clip plays on a COLLADA skin's skeleton just as a COLLADA clip does. Read here the same way:

- HIERARCHY: each `ROOT`/`JOINT` with its `OFFSET` (its rest translation from its parent) and its
  `CHANNELS` (`Xposition`/`Yposition`/`Zposition`, `Xrotation`/`Yrotation`/`Zrotation`), in the
  order listed; an `End Site` only closes a chain and is skipped.
- MOTION: `Frames:`, `Frame Time:` (seconds), then one line of channel values a frame, the
  joints' channels in HIERARCHY order. Frame k is keyed at k·Frame Time.
- A joint's local transform at a frame: its translation is its OFFSET, each position channel
  replacing its own component (BVHLoader sets the component, it does not add); its rotation is
  the rotation channels' turns, in degrees, composed in the order listed (the first leftmost:
  `Zrotation Xrotation Yrotation` is Rz·Rx·Ry, applied to a child's points Y first).
- `<animation><scale>` multiplies the OFFSETs and position channels (BVHLoader's `_scale`): the
  BVH's units to the skin's; the skin's own joints are not scaled.
- Each BVH joint drives the skin joint of its name (a BVH made for the skin names its joints as
  the skin does; gz-common pairs them in node order once the two trees have the same shape, and
  re-aligns rest poses that differ, which a BVH made for the skin does not need). A skin joint
  the BVH lacks keeps its rest transform.

A file that cannot be used raises `SkeletonError` saying why; the caller warns and draws the
skin unanimated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simbot.description.skeletons import F64, Clip, Skeleton, SkeletonError
from simbot.transform import axis_rotations, matmul

AXES = {"x": 0, "y": 1, "z": 2}


@dataclass
class _Joint:
    """A BVH joint as its HIERARCHY block declares it."""

    name: str
    parent: str | None
    offset: F64 = field(default_factory=lambda: np.zeros(3))
    channels: tuple[str, ...] = ()


def read_bvh_clip(path: Path, skeleton: Skeleton, scale: float = 1.0) -> Clip:
    """The BVH file's motion of `skeleton`, translations times `scale`; SkeletonError saying why
    where it cannot be read or names a joint the skin lacks."""
    hierarchy, motion = _sections(path)
    joints = _joints(hierarchy)
    indices = [_skin_joint(joint, skeleton) for joint in joints]
    times, values = _frames(motion, sum(len(joint.channels) for joint in joints))
    locals_ = np.tile(skeleton.rest, (len(times), 1, 1, 1))
    column = 0
    for joint, index in zip(joints, indices, strict=True):
        width = len(joint.channels)
        locals_[:, index] = _locals(joint, values[:, column : column + width], scale)
        column += width
    return Clip(times, locals_)


def _sections(path: Path) -> tuple[list[str], list[str]]:
    """The HIERARCHY's words and the MOTION's non-blank lines."""
    try:
        lines = [line.strip() for line in path.read_text().splitlines()]
    except (OSError, UnicodeDecodeError) as exc:
        raise SkeletonError(f"cannot be read ({exc})") from None
    lines = [line for line in lines if line]
    if not lines or lines[0] != "HIERARCHY":
        raise SkeletonError("not a BVH file: it does not begin with HIERARCHY")
    if "MOTION" not in lines:
        raise SkeletonError("no MOTION section")
    split = lines.index("MOTION")
    return " ".join(lines[1:split]).split(), lines[split + 1 :]


def _joints(words: list[str]) -> list[_Joint]:
    """The HIERARCHY's joints in file order (their channels' order in a frame line)."""
    joints: list[_Joint] = []
    blocks: list[_Joint | None] = []  # the open `{`s: a joint's, or None for an End Site's
    declared: _Joint | None = None
    at = 0
    while at < len(words):
        word = words[at]
        if word in ("ROOT", "JOINT") and at + 1 < len(words):
            parent = blocks[-1] if blocks else None
            declared = _Joint(words[at + 1], parent.name if parent is not None else None)
            joints.append(declared)
            at += 2
        elif word == "End":
            declared, at = None, at + 2
        elif word == "{":
            blocks.append(declared)
            at += 1
        elif word == "}" and blocks:
            blocks.pop()
            at += 1
        elif word == "OFFSET" and blocks:
            owner = blocks[-1]
            offset = [_number(w, "OFFSET") for w in words[at + 1 : at + 4]]
            if len(offset) != 3:
                raise SkeletonError(f"HIERARCHY: OFFSET {' '.join(words[at + 1 : at + 4])}: not 3 numbers")
            if owner is not None:
                owner.offset = np.array(offset)
            at += 4
        elif word == "CHANNELS" and blocks and blocks[-1] is not None:
            at = _channels(blocks[-1], words, at)
        else:
            raise SkeletonError(f"HIERARCHY: unexpected {word!r}")
    if not joints:
        raise SkeletonError("HIERARCHY: no ROOT joint")
    return joints


def _channels(joint: _Joint, words: list[str], at: int) -> int:
    """Reads `CHANNELS n name…` at `at` into `joint`; the index of the word after it."""
    count = int(_number(words[at + 1] if at + 1 < len(words) else "", f"joint {joint.name!r}: CHANNELS"))
    names = tuple(words[at + 2 : at + 2 + count])
    bad = next((n for n in names if n[:1].lower() not in AXES or n[1:].lower() not in ("position", "rotation")), None)
    if len(names) != count or bad is not None:
        raise SkeletonError(f"joint {joint.name!r}: CHANNELS {count} {' '.join(names)}: not {count} channel names")
    joint.channels = names
    return at + 2 + count


def _number(word: str, where: str) -> float:
    try:
        value = float(word)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SkeletonError(f"{where}: {word!r} is not a number")
    return value


def _skin_joint(joint: _Joint, skeleton: Skeleton) -> int:
    """The skin joint of the BVH joint's name, which must hang from the skin joint its BVH parent names."""
    if joint.name not in skeleton.names:
        raise SkeletonError(f"joint {joint.name!r}: the skin has no joint of that name")
    index = skeleton.index(joint.name)
    parent = skeleton.parents[index]
    skin_parent = skeleton.names[parent] if parent >= 0 else None
    if joint.parent is not None and joint.parent != skin_parent:
        raise SkeletonError(f"joint {joint.name!r}: its parent is {joint.parent!r}, in the skin {skin_parent!r}")
    return index


def _frames(motion: list[str], width: int) -> tuple[F64, F64]:
    """Key times (k·Frame Time) and the K×width channel values of the MOTION section."""
    header = [line.split() for line in motion[:2]]
    if len(header) < 2 or header[0][:1] != ["Frames:"] or header[1][:2] != ["Frame", "Time:"]:
        raise SkeletonError("MOTION: it does not begin with 'Frames:' and 'Frame Time:'")
    count = _number(" ".join(header[0][1:]), "MOTION: Frames")
    step = _number(" ".join(header[1][2:]), "MOTION: Frame Time")
    rows = motion[2:]
    if count < 1 or not rows:
        raise SkeletonError("MOTION: no frames")
    if count != len(rows):
        raise SkeletonError(f"MOTION: Frames: {count:g}, but {len(rows)} frame lines")
    if not step > 0.0 and len(rows) > 1:
        raise SkeletonError(f"MOTION: Frame Time {step:g} s: not a positive time")
    values = np.zeros((len(rows), width))
    for k, row in enumerate(rows):
        words = row.split()
        if len(words) != width:
            raise SkeletonError(f"MOTION: frame {k}: {len(words)} values, but the HIERARCHY's CHANNELS are {width}")
        values[k] = [_number(word, f"MOTION: frame {k}") for word in words]
    return np.arange(len(rows), dtype=np.float64) * step, values


def _locals(joint: _Joint, values: F64, scale: float) -> F64:
    """K×4×4 local transforms of a joint from its K×channels values (see the module docstring)."""
    out = np.tile(np.eye(4), (len(values), 1, 1))
    out[:, :3, 3] = joint.offset * scale
    for column, channel in enumerate(joint.channels):
        axis = AXES[channel[0].lower()]
        if channel[1:].lower() == "position":
            out[:, axis, 3] = values[:, column] * scale
        else:
            out[:, :3, :3] = matmul(out[:, :3, :3], axis_rotations(np.eye(3)[axis], np.radians(values[:, column])))
    return out
