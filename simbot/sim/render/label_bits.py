"""What a renderer's `labels` buffer holds in each pixel: one uint32 packing the label and the
instance of the visual seen there, so that segmentation and bounding-box cameras read both from
one draw.

    bits 0..15   the body's instance number (`SceneBody.instance`; 0: nothing drawn, the sky)
    bits 16..23  the label (Gazebo's Label system, 0..255)
    bit  24      set where the visual has a label (unlabelled geometry still hides what lies behind it)
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

LABELLED = 1 << 24
MAX_INSTANCE = 0xFFFF

Packed = npt.NDArray[np.uint32]


def pack(label: int | None, instance: int) -> int:
    """The pixel value of a visual with this label (None: none) on the body of this instance."""
    instance &= MAX_INSTANCE
    return instance if label is None else LABELLED | (label << 16) | instance


def labelled(packed: Packed) -> npt.NDArray[np.bool_]:
    return (packed & LABELLED) != 0


def label_of(packed: Packed) -> npt.NDArray[np.uint8]:
    return ((packed >> 16) & 0xFF).astype(np.uint8)


def instance_of(packed: Packed) -> npt.NDArray[np.uint16]:
    return (packed & MAX_INSTANCE).astype(np.uint16)
