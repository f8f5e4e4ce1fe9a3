"""Where `model://`, `package://`, relative and bare file names point: the resource path.

Search order: SIMBOT_RESOURCE_PATH, then Gazebo's GZ_SIM_RESOURCE_PATH and
IGN_GAZEBO_RESOURCE_PATH (so an existing Gazebo setup works unchanged), then simbot's own
assets. Each variable is a list of folders separated by os.pathsep.

A Fuel URL (`https://fuel.gazebosim.org/1.0/OWNER/models/NAME[/VERSION][/files/PATH]`) is
looked up in the local Fuel cache as Gazebo lays it out (GZ_FUEL_CACHE_PATH, default
~/.gz/fuel: `fuel.gazebosim.org/owner/models/name/VERSION/`), the newest version when the URL
names none. simbot downloads nothing.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

RESOURCE_PATH_VARIABLES = ("SIMBOT_RESOURCE_PATH", "GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH")
PACKAGE_NAME = "simbot"
FUEL_CACHE_VARIABLES = ("GZ_FUEL_CACHE_PATH", "IGN_FUEL_CACHE_PATH")
REMOTE_SCHEMES = ("http", "https")


def asset_root() -> Path:
    """The folder holding urdf/, meshes/ and worlds/.

    A wheel carries them inside the package (simbot/assets); a source checkout or an
    editable install has them at the top of the repository.
    """
    package_dir = Path(__file__).resolve().parents[1]
    installed = package_dir / "assets"
    return installed if installed.is_dir() else package_dir.parent


def asset(relative: str) -> Path:
    """A file of simbot's own assets, e.g. asset('urdf/flexley_tug.sdf')."""
    return asset_root() / relative


def resource_path() -> list[Path]:
    """The folders searched for models and files, in order."""
    folders = [
        Path(entry)
        for variable in RESOURCE_PATH_VARIABLES
        for entry in os.environ.get(variable, "").split(os.pathsep)
        if entry
    ]
    root = asset_root()
    return folders + [root / "worlds" / "models", root]


@dataclass(frozen=True)
class Resolution:
    """Where a URI points (None when nowhere) and every place that was looked at."""

    uri: str
    path: Path | None
    tried: tuple[Path, ...]

    def describe_tried(self) -> str:
        """The places looked at, for a warning or an error."""
        tried = ", ".join(str(p) for p in self.tried)
        if urlparse(self.uri).scheme in REMOTE_SCHEMES:
            return f"the local Fuel cache: {tried or fuel_cache()}; simbot downloads nothing"
        return tried or "nowhere (empty resource path)"


def _first_existing(uri: str, candidates: list[Path]) -> Resolution:
    found = next((c for c in candidates if c.exists()), None)
    return Resolution(uri, found, tuple(candidates))


def _package_candidates(package: str, rest: str) -> list[Path]:
    """A ROS package is a folder of that name on the path, or a path entry named so."""
    candidates = [folder / package / rest for folder in resource_path()]
    candidates += [folder / rest for folder in resource_path() if folder.name == package]
    if package == PACKAGE_NAME:
        candidates.append(asset_root() / rest)
    return candidates


def fuel_cache() -> Path:
    """The local Fuel cache folder (Gazebo's GZ_FUEL_CACHE_PATH, or its default)."""
    folder = next((os.environ[v] for v in FUEL_CACHE_VARIABLES if os.environ.get(v)), "~/.gz/fuel")
    return Path(folder).expanduser()


def _fuel_candidates(host: str, path: str) -> list[Path]:
    """Where Gazebo's Fuel client would have stored what a Fuel URL names (owner and name are
    stored lower-case; the exact spelling is tried first)."""
    parts = [unquote(p) for p in path.split("/") if p]
    if parts and re.fullmatch(r"\d+(\.\d+)*", parts[0]):
        parts = parts[1:]  # the API version, "1.0"
    if len(parts) < 3 or parts[1].lower() != "models":
        return []
    owner, name, rest = parts[0], parts[2], parts[3:]
    version = rest.pop(0) if rest and (rest[0].isdigit() or rest[0] == "tip") else "tip"
    rest = rest[1:] if rest[:1] == ["files"] else rest
    candidates = []
    for folder in dict.fromkeys(
        fuel_cache() / host / o / "models" / n for o, n in ((owner, name), (owner.lower(), name.lower()))
    ):
        versions = (
            sorted((int(v.name) for v in folder.glob("*") if v.name.isdigit()), reverse=True) if folder.is_dir() else []
        )
        chosen = versions[:1] if version == "tip" else [int(version)]
        candidates += [folder.joinpath(str(v), *rest) for v in chosen] or [folder]
    return candidates


def resolve(uri: str, base_dir: Path | None = None) -> Resolution:
    """The file or folder `uri` names, relative to `base_dir` when it is a relative path."""
    parsed = urlparse(uri)
    rest = unquote(parsed.netloc + parsed.path).lstrip("/")
    if parsed.scheme == "model":
        return _first_existing(uri, [folder / rest for folder in resource_path()])
    if parsed.scheme == "package":
        package, _, inner = rest.partition("/")
        return _first_existing(uri, _package_candidates(package, inner))
    if parsed.scheme == "file":
        return _first_existing(uri, [Path(unquote(parsed.path))])
    if parsed.scheme in REMOTE_SCHEMES:
        return _first_existing(uri, _fuel_candidates(parsed.netloc.lower(), parsed.path))
    if parsed.scheme:
        return Resolution(uri, None, ())
    path = Path(uri).expanduser()
    if path.is_absolute():
        return _first_existing(uri, [path])
    local = [base_dir / path] if base_dir is not None else [Path.cwd() / path]
    return _first_existing(uri, local + [folder / path for folder in resource_path()])
