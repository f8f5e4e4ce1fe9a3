"""Segmentation outputs (`kinds.py`), finished from the packed `labels` buffer (`label_bits.py`) in the
render worker: the labels map and the colored map of Gazebo's segmentation camera, rgb8 each.

Labels map, per pixel in message byte order (gz-rendering's Ogre2SegmentationCamera):
- semantic: [label, label, label];
- instance / panoptic (Gazebo treats them alike): [count & 0xFF, count >> 8, label], where count is
  the object's 16-bit instance number. Gazebo counts the objects of each label 1, 2, ...; simbot
  gives each body one number across the world (`SceneBody.instance`), so two objects of one label
  differ, and an object keeps its number from frame to frame whatever else comes into view.

Background, [0, 0, 0] in both maps: the sky, unlabelled geometry, and label 0 (Gazebo's background
label), as in Gazebo.

Colored map: one colour per label (semantic) or per (label, instance) (instance / panoptic), from a
hash of that key (`colour_of`): the same in every frame, every run and every camera, never black.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from simbot.sim.render.kinds import Array, Finish, Optics, OutputKind

SEMANTIC = "semantic"
PANOPTIC = "panoptic"
MIN_CHANNEL = 32
"""Every channel of a colour lies in 32..255, so no object is drawn in the background's black."""
SCALE = (MIN_CHANNEL + np.arange(256) * (255 - MIN_CHANNEL) // 255).astype(np.uint8)
"""A hash byte → a channel in 32..255."""
LABEL_BYTE = 2
"""Of a packed pixel's four bytes in memory (little-endian: instance low, instance high, label,
flags), the label's: the layout of `label_bits.py` is nearly the panoptic labels map already."""

Keys = npt.NDArray[np.uint32]


def _bytes(packed: Array) -> npt.NDArray[np.uint8]:
    """The packed buffer's bytes, H×W×4 (a view)."""
    out: npt.NDArray[np.uint8] = packed.view(np.uint8).reshape(*packed.shape, 4)
    return out


def colour_of(keys: Keys) -> npt.NDArray[np.uint8]:
    """Colours (…×3) of keys (a label << 16, or label << 16 | instance): MurmurHash3's 32-bit
    finaliser of the key, its bytes 0, 1, 2 (least significant first) as red, green and blue, each
    scaled into 32..255 (`SCALE`)."""
    h = keys.astype(np.uint32)
    h ^= h >> np.uint32(16)
    h *= np.uint32(0x85EBCA6B)
    h ^= h >> np.uint32(13)
    h *= np.uint32(0xC2B2AE35)
    h ^= h >> np.uint32(16)
    out: npt.NDArray[np.uint8] = SCALE[h.view(np.uint8).reshape(*h.shape, 4)[..., :3]]
    return out


SEMANTIC_COLOURS = colour_of(np.arange(256, dtype=np.uint32) << np.uint32(16))
SEMANTIC_COLOURS[0] = 0
"""Each label's colour; label 0 (background) black."""


def _foreground(packed: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """H×W×1: 1 where a pixel shows a label other than background's 0, else 0."""
    out: npt.NDArray[np.uint8] = (packed[..., LABEL_BYTE, np.newaxis] != 0).view(np.uint8)
    return out


def _semantic_labels(_: Optics) -> Finish:
    """The label byte in all three channels (0 for the sky and unlabelled geometry, whose label bits are 0)."""

    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        out[...] = _bytes(arrays["labels"])[..., LABEL_BYTE, np.newaxis]

    return finish


def _panoptic_labels(_: Optics) -> Finish:
    """The packed pixel's first three bytes, [count & 0xFF, count >> 8, label]; background zeroed."""

    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        packed = _bytes(arrays["labels"])
        np.multiply(packed[..., :3], _foreground(packed), out=out)

    return finish


def _semantic_colors(_: Optics) -> Finish:
    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        out[...] = SEMANTIC_COLOURS[_bytes(arrays["labels"])[..., LABEL_BYTE]]

    return finish


def _panoptic_colors(_: Optics) -> Finish:
    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        packed = arrays["labels"]
        np.multiply(colour_of(packed & np.uint32(0xFFFFFF)), _foreground(_bytes(packed)), out=out)

    return finish


SEMANTIC_LABELS = OutputKind("semantic_labels", np.uint8, 3, "rgb8", needs=("labels",), finisher=_semantic_labels)
PANOPTIC_LABELS = OutputKind("panoptic_labels", np.uint8, 3, "rgb8", needs=("labels",), finisher=_panoptic_labels)
SEMANTIC_COLORS = OutputKind("semantic_colors", np.uint8, 3, "rgb8", needs=("labels",), finisher=_semantic_colors)
PANOPTIC_COLORS = OutputKind("panoptic_colors", np.uint8, 3, "rgb8", needs=("labels",), finisher=_panoptic_colors)
OUTPUTS = {
    SEMANTIC: (SEMANTIC_LABELS.name, SEMANTIC_COLORS.name),
    PANOPTIC: (PANOPTIC_LABELS.name, PANOPTIC_COLORS.name),
}
"""The (labels map, colored map) outputs of each segmentation type."""
