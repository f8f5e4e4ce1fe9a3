"""A non-editable install works away from the repository: the wheel carries the assets and finds them.

One module fixture builds the wheel (pip with build isolation, so the build backend need not be
in the dev venv) and installs it with its dependencies and the gym extra into a fresh venv; the
tests then run that venv's python and `simbot` from an empty folder, with no resource path
variables set, and from the checkout's own folder, whose `simbot/` then shadows the installed one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from simbot.description.resources import RESOURCE_PATH_VARIABLES

REPO = Path(__file__).resolve().parents[1]
ROBOT_LINKS = (
    "base_footprint", "base_link", "imu_link", "base_scan_front", "base_scan_back",
    "front_left_wheel", "front_right_wheel", "back_left_wheel", "back_right_wheel",
    "castor_front_right", "castor_front_left", "castor_back_right", "castor_back_left",
)  # fmt: skip
PACKAGED = (
    "simbot/assets/urdf/flexley_tug.sdf",
    "simbot/assets/urdf/flexley_tug.urdf",
    "simbot/assets/meshes/chassis.stl",
    "simbot/assets/worlds/warehouse.sdf",
    "simbot/assets/worlds/models/trolley/model.sdf",
)


@dataclass(frozen=True)
class Installed:
    """A wheel of the repository and a fresh venv it is installed in."""

    wheel: Path
    venv: Path
    site_packages: Path
    cwd: Path
    env: dict[str, str]

    def run(self, *args: str) -> subprocess.CompletedProcess[str]:
        """A program of the venv's bin/, run from the empty folder; never raises on failure."""
        program = str(self.venv / "bin" / args[0])
        command = [program, *args[1:]]
        return subprocess.run(command, cwd=self.cwd, env=self.env, capture_output=True, text=True, timeout=300)

    def asset(self, relative: str) -> Path:
        """Where the installed simbot says its own asset lies."""
        code = f"from simbot.description.resources import asset; print(asset({relative!r}))"
        done = self.run("python", "-c", code)
        assert done.returncode == 0, done.stderr
        return Path(done.stdout.strip())

    def describe(self, path: Path) -> str:
        """`simbot describe` output; fails on a non-zero exit or any warning (e.g. a missing mesh)."""
        done = self.run("simbot", "describe", str(path))
        assert done.returncode == 0, done.stderr
        assert "WARNING" not in done.stderr, done.stderr
        return done.stdout


def clean_env() -> dict[str, str]:
    """This process's environment without anything that points Python or simbot at the repository."""
    dropped = {*RESOURCE_PATH_VARIABLES, "PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONSTARTUP"}
    return {k: v for k, v in os.environ.items() if k not in dropped}


def pip(python: Path | str, *args: str, cwd: Path, env: dict[str, str]) -> None:
    """Run pip, failing with its output."""
    command = [str(python), "-m", "pip", *args]
    done = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"pip {' '.join(args)}:\n{done.stdout}\n{done.stderr}"


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    """Build the wheel, make a fresh venv, install the wheel and its dependencies into it."""
    root = tmp_path_factory.mktemp("install")
    env, dist, venv, cwd = clean_env(), root / "dist", root / "venv", root / "elsewhere"
    cwd.mkdir()
    pip(sys.executable, "wheel", "--no-deps", "-w", str(dist), str(REPO), cwd=cwd, env=env)
    (wheel,) = dist.glob("simbot-*.whl")
    subprocess.run([sys.executable, "-m", "venv", str(venv)], cwd=cwd, env=env, check=True, timeout=300)
    pip(venv / "bin" / "python", "install", f"{wheel}[gym]", cwd=cwd, env=env)
    installed = Installed(wheel, venv, Path(), cwd, env)
    purelib = installed.run("python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])")
    assert purelib.returncode == 0, purelib.stderr
    return replace(installed, site_packages=Path(purelib.stdout.strip()).resolve())


def test_wheel_carries_the_assets(installed: Installed) -> None:
    """The wheel holds the robot (SDF and URDF), its meshes, and the worlds with their models."""
    with zipfile.ZipFile(installed.wheel) as wheel:
        names = set(wheel.namelist())
    assert set(PACKAGED) <= names, sorted(set(PACKAGED) - names)
    assert not any(".mypy_cache" in n or "__pycache__" in n for n in names)


def test_wheel_installs_only_simbot(installed: Installed) -> None:
    """Every package of the checkout is in the wheel under simbot's name; nothing else is top level.

    The clients (`clients/` in the repository) install as `simbot.clients`, so a wheel never puts a
    package named `clients` into site-packages, where it would collide with anyone else's.
    """
    with zipfile.ZipFile(installed.wheel) as wheel:
        names = set(wheel.namelist())
    assert {name.split("/")[0] for name in names} == {"simbot", f"{installed.wheel.name.split('-py')[0]}.dist-info"}
    packages = {p.relative_to(REPO).as_posix() for p in REPO.glob("simbot/**/__init__.py")}
    clients = {f"simbot/{p.relative_to(REPO).as_posix()}" for p in REPO.glob("clients/*.py")}
    assert packages | clients <= names, sorted((packages | clients) - names)
    done = installed.run("python", "-c", "import clients")
    assert done.returncode != 0 and "No module named 'clients'" in done.stderr, done.stderr


def test_editable_install_has_no_top_level_clients(tmp_path: Path) -> None:
    """The dev venv's editable install maps simbot.clients onto the checkout's clients/ and no more.

    Run away from the checkout (whose folder is on sys.path only as the working directory).
    """
    code = "import importlib.util as u, simbot.clients.teleop as t; print(t.__file__, u.find_spec('clients'))"
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=clean_env(), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    teleop, spec = done.stdout.split()
    assert Path(teleop) == REPO / "clients" / "teleop.py" and spec == "None", done.stdout


def test_installed_simbot_is_not_the_repository(installed: Installed) -> None:
    """The fresh venv imports simbot from its own site-packages, not from the repository."""
    done = installed.run("python", "-c", "import simbot; print(simbot.__file__)")
    assert done.returncode == 0, done.stderr
    module = Path(done.stdout.strip()).resolve()
    assert module.is_relative_to(installed.site_packages), module
    assert not module.is_relative_to(REPO)


def test_describe_packaged_robot(installed: Installed) -> None:
    """The packaged robot SDF lies in site-packages, and `simbot describe` finds its meshes and 13 links."""
    sdf = installed.asset("urdf/flexley_tug.sdf").resolve()
    assert sdf.is_relative_to(installed.site_packages), sdf
    assert sdf.is_file()
    out = installed.describe(sdf)
    assert "links (13)" in out
    rows = {line.split()[0] for line in out.splitlines() if line.strip()}
    assert set(ROBOT_LINKS) <= rows, sorted(set(ROBOT_LINKS) - rows)


def test_describe_packaged_warehouse(installed: Installed) -> None:
    """`simbot describe` of the packaged warehouse resolves model://trolley inside the installed package."""
    world = installed.asset("worlds/warehouse.sdf").resolve()
    assert world.is_relative_to(installed.site_packages), world
    out = installed.describe(world)
    trolley_rows = [line.split() for line in out.splitlines() if line.startswith("trolley ")]
    assert len(trolley_rows) == 1 and trolley_rows[0][-1] == "model://trolley", trolley_rows
    trolley_sdf = installed.site_packages / "simbot" / "assets" / "worlds" / "models" / "trolley" / "model.sdf"
    assert f"from {trolley_sdf}" in out


CLIENTS = (
    "teleop",
    "merger",
    "stitcher",
    "dock",
    "topics",
    "echo",
    "monitor",
    "snapshot",
    "launch",
    "state",
    "record",
    "play",
    "foxglove",
)
CLIENT_SCRIPTS = ("simbot-teleop", "simbot-merger", "simbot-stitcher", "simbot-dock")


def test_installed_clients_run_from_their_console_scripts_and_simbot(installed: Installed) -> None:
    """The wheel carries `simbot.clients`: each console script and each `simbot <client>` answers --help."""
    for script in CLIENT_SCRIPTS:
        done = installed.run(script, "--help")
        assert done.returncode == 0 and "--connect" in done.stdout, f"{script}: {done.stderr}"
    for command in CLIENTS:
        done = installed.run("simbot", command, "--help")
        assert done.returncode == 0 and "--namespace" in done.stdout, f"simbot {command}: {done.stderr}"


IMPORT_ALL = """
import importlib, json, sys
failed = {}
for name in sys.argv[1:]:
    try:
        importlib.import_module(name)
    except ModuleNotFoundError as exc:
        failed[name] = [exc.name or "", str(exc)]
    except Exception as exc:
        failed[name] = ["", f"{type(exc).__name__}: {exc}"]
print(json.dumps(failed))
"""
OPTIONAL = {"foxglove", "rclpy", "ray", "stable_baselines3", "torch"}
"""What the extras the fixture leaves out bring (foxglove, ros2, ray, learning): a module that needs one may not import."""


def _public_modules(wheel: Path) -> list[str]:
    """Every module of the wheel whose dotted name has no part starting with an underscore (no
    `__main__`), the assets' scripts aside."""
    with zipfile.ZipFile(wheel) as archive:
        paths = [n for n in archive.namelist() if n.startswith("simbot/") and n.endswith(".py")]
    names = {path.removesuffix(".py").removesuffix("/__init__").replace("/", ".") for path in paths}
    return sorted(
        n for n in names if not n.startswith("simbot.assets") and not any(p.startswith("_") for p in n.split("."))
    )


def test_every_public_module_imports_beside_a_checkout(installed: Installed) -> None:
    """From the checkout's folder, `python -c` finds the checkout's `simbot/` first, which holds no
    `simbot.clients` (setuptools maps it from clients/): the library must never reach into the
    client programs, so every library module imports there. The clients themselves import as the
    console scripts run them, from sys.path without the working directory (`-I`)."""
    modules = _public_modules(installed.wheel)
    library = [m for m in modules if not m.startswith("simbot.clients")]
    clients = [m for m in modules if m.startswith("simbot.clients")]
    assert "simbot.gym.observe" in library and "simbot.clients.merger" in clients, modules
    python = str(installed.venv / "bin" / "python")
    for flags, names in (([], library), (["-I"], clients)):
        done = subprocess.run(
            [python, *flags, "-c", IMPORT_ALL, *names], cwd=REPO, env=installed.env, capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr[-3000:]
        failed = json.loads(done.stdout)
        needed = {name: why for name, (missing, why) in failed.items() if missing.split(".")[0] not in OPTIONAL}
        assert needed == {}, f"python {' '.join(flags)} -c 'import …' in {REPO}: {needed}"
