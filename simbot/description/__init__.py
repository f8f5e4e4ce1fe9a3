"""The description layer: SDF and URDF files into plain typed data, and URDF out.

It knows nothing of physics or transport. `load_description` is the one entry point that
takes any file a user may hand over: an SDF world or model, a URDF, or a xacro file.
"""

from __future__ import annotations

from pathlib import Path

from simbot.description.errors import DescriptionError
from simbot.description.model import Model, World
from simbot.description.sdf_reader import load_model, load_sdf, load_world
from simbot.description.urdf_reader import load_urdf_model
from simbot.description.urdf_writer import model_to_urdf

URDF_SUFFIXES = (".urdf", ".xacro")

__all__ = [
    "DescriptionError",
    "Model",
    "World",
    "load_description",
    "load_model",
    "load_sdf",
    "load_urdf_model",
    "load_world",
    "model_to_urdf",
]


def load_description(path: Path | str) -> Model | World:
    """An SDF world or model, or a URDF / xacro robot, by the file's suffix."""
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(path, "no such file")
    if path.suffix in URDF_SUFFIXES:
        return load_urdf_model(path)
    return load_sdf(path)
