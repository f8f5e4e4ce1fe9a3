"""Segmentation outputs (`kinds.py`), finished from the packed `labels` buffer (`labels.py`) in the
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

from simbot.sim.render.kinds import Array, Finish, Intrinsics, OutputKind
from simbot.sim.render.labels import label_of, labelled

SEMANTIC = "semantic"
PANOPTIC = "panoptic"
MIN_CHANNEL = 32
"""Every channel of a colour lies in 32..255, so no object is drawn in the background's black."""

Keys = npt.NDArray[np.uint32]


def _foreground(packed: Array) -> npt.NDArray[np.bool_]:
    """Pixels of a labelled visual with a label other than the background's 0."""
    return labelled(packed) & (((packed >> 16) & 0xFF) != 0)


def colour_of(keys: Keys) -> npt.NDArray[np.uint8]:
    """H×W×3 colours of keys (a label, or label << 16 | instance): MurmurHash3's 32-bit finaliser of
    the key, its low three bytes as red, green and blue, each scaled into 32..255."""
    h = keys.astype(np.uint32)
    h ^= h >> np.uint32(16)
    h *= np.uint32(0x85EBCA6B)
    h ^= h >> np.uint32(13)
    h *= np.uint32(0xC2B2AE35)
    h ^= h >> np.uint32(16)
    channels = np.stack([(h >> np.uint32(shift)) & np.uint32(0xFF) for shift in (16, 8, 0)], axis=-1)
    return (MIN_CHANNEL + channels * (255 - MIN_CHANNEL) // 255).astype(np.uint8)


def _semantic_labels(_: Intrinsics) -> Finish:
    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        packed = arrays["labels"]
        label = np.where(_foreground(packed), label_of(packed), np.uint8(0))
        out[...] = label[..., np.newaxis]

    return finish


def _panoptic_labels(_: Intrinsics) -> Finish:
    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        packed = arrays["labels"]
        shown = np.where(_foreground(packed), packed, np.uint32(0))
        out[..., 0] = shown & 0xFF
        out[..., 1] = (shown >> 8) & 0xFF
        out[..., 2] = (shown >> 16) & 0xFF

    return finish


def _colored(key_mask: int) -> Finish:
    """Colours of the packed value's bits under `key_mask` (label, or label and instance)."""

    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        packed = arrays["labels"]
        foreground = _foreground(packed)
        out[...] = np.where(foreground[..., np.newaxis], colour_of(packed & np.uint32(key_mask)), np.uint8(0))

    return finish


def _semantic_colors(_: Intrinsics) -> Finish:
    return _colored(0xFF0000)


def _panoptic_colors(_: Intrinsics) -> Finish:
    return _colored(0xFFFFFF)


SEMANTIC_LABELS = OutputKind("semantic_labels", np.uint8, 3, "rgb8", needs=("labels",), finisher=_semantic_labels)
PANOPTIC_LABELS = OutputKind("panoptic_labels", np.uint8, 3, "rgb8", needs=("labels",), finisher=_panoptic_labels)
SEMANTIC_COLORS = OutputKind("semantic_colors", np.uint8, 3, "rgb8", needs=("labels",), finisher=_semantic_colors)
PANOPTIC_COLORS = OutputKind("panoptic_colors", np.uint8, 3, "rgb8", needs=("labels",), finisher=_panoptic_colors)
OUTPUTS = {
    SEMANTIC: (SEMANTIC_LABELS.name, SEMANTIC_COLORS.name),
    PANOPTIC: (PANOPTIC_LABELS.name, PANOPTIC_COLORS.name),
}
"""The (labels map, colored map) outputs of each segmentation type."""
