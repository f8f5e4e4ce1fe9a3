"""A world and the files added to it: simbot's own worlds and additions by name, and `--add`'s
models joined to a world's (what `simbot-server`, the map and the Gymnasium environments load alike)."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from simbot.description import load_description
from simbot.description.errors import DescriptionError
from simbot.description.model import World
from simbot.description.resources import asset

log = logging.getLogger(__name__)

ADDITIONS = "worlds/additions"
"""Where simbot's own files for `--add` are, by name."""


def world_path(name_or_path: str) -> Path:
    """A world file, or the name of one of simbot's own worlds (`warehouse`, `empty`)."""
    return _sdf_file(name_or_path, "worlds", "world file or built-in world")


def addition_path(name_or_path: str) -> Path:
    """An SDF file to add, or the name of one of simbot's own (`warehouse_people`, in worlds/additions/)."""
    return _sdf_file(name_or_path, ADDITIONS, "file or built-in addition")


def _sdf_file(name_or_path: str, folder: str, what: str) -> Path:
    """A path as given (an .sdf, or anything that exists), else simbot's own `folder/<name>.sdf`;
    DescriptionError listing the built-in names when neither."""
    path = Path(name_or_path)
    if path.suffix == ".sdf" or path.exists():
        return path
    own = asset(f"{folder}/{name_or_path}.sdf")
    if own.is_file():
        return own
    known = sorted(p.stem for p in asset(folder).glob("*.sdf"))
    raise DescriptionError(path, f"no such {what} (built-in: {', '.join(known)})")


def with_additions(world: World, paths: Sequence[Path]) -> World:
    """`world` with the models and actors of each file (a `<world>` holding them, or one model or
    actor), loaded as the world's own: reset puts them back where they started, as their file says.
    Only models join: an added world's lights, plugins and settings are a warning, not applied."""
    models = list(world.models)
    for path in paths:
        loaded = load_description(path)
        added = list(loaded.models) if isinstance(loaded, World) else [loaded]
        if not added:
            raise DescriptionError(path, "holds no <model> or <actor> to add to the world")
        if isinstance(loaded, World) and (loaded.plugins or loaded.lights):
            log.warning("%s: only its models and actors are added, not its lights or world plugins", path)
        taken = {model.name for model in models}
        for model in added:
            if model.name in taken:
                raise DescriptionError(path, f"model {model.name!r} is already in world {world.name!r}", "model")
            taken.add(model.name)
        models += added
    return replace(world, models=tuple(models))
