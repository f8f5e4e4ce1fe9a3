"""The resource path: SIMBOT_RESOURCE_PATH, then Gazebo's variables, then simbot's own assets."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from conftest import REPO

from simbot.description import load_model
from simbot.description.resources import asset, resolve


def _tree(root: Path, *files: str) -> Path:
    for name in files:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(name)
    return root


def test_search_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """model:// is found on SIMBOT_RESOURCE_PATH before GZ_SIM_RESOURCE_PATH before IGN_GAZEBO_RESOURCE_PATH."""
    first, second, third = (_tree(tmp_path / n, "crate/model.sdf") for n in ("a", "b", "c"))
    monkeypatch.setenv("IGN_GAZEBO_RESOURCE_PATH", str(third))
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", f"{tmp_path / 'missing'}:{second}")
    assert resolve("model://crate/model.sdf").path == second / "crate" / "model.sdf"
    monkeypatch.setenv("SIMBOT_RESOURCE_PATH", str(first))
    assert resolve("model://crate/model.sdf").path == first / "crate" / "model.sdf"


def test_package_assets_come_last(clean_resource_path: None) -> None:
    """With no variables set, model:// and package://simbot reach the package's own assets."""
    assert resolve("model://trolley").path == asset("worlds/models/trolley")
    assert resolve("package://simbot/meshes/wheel.stl").path == asset("meshes/wheel.stl")
    assert asset("urdf/flexley_tug.sdf").resolve() == (REPO / "urdf" / "flexley_tug.sdf").resolve()


def test_relative_bare_and_package_names(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative paths are taken from the file's folder first; bare names and ROS packages from the path."""
    _tree(tmp_path, "robot/urdf/x.sdf", "robot/meshes/body.stl", "lib/shared.stl", "lib/my_pkg/meshes/arm.dae")
    monkeypatch.setenv("SIMBOT_RESOURCE_PATH", str(tmp_path / "lib"))
    base = tmp_path / "robot" / "urdf"
    assert resolve("../meshes/body.stl", base).path == base / "../meshes/body.stl"
    assert resolve("shared.stl", base).path == tmp_path / "lib" / "shared.stl"
    assert resolve("package://my_pkg/meshes/arm.dae").path == tmp_path / "lib" / "my_pkg" / "meshes" / "arm.dae"
    assert resolve(f"file://{tmp_path}/lib/shared.stl").path == tmp_path / "lib" / "shared.stl"
    missing = resolve("model://nothing/here.stl")
    assert (
        missing.path is None
        and len(missing.tried) >= 3
        and str(tmp_path / "lib" / "nothing" / "here.stl") in missing.describe_tried()
    )


def test_missing_mesh_warns_with_paths_and_falls_back(
    tmp_path: Path, clean_resource_path: None, caplog: pytest.LogCaptureFixture
) -> None:
    """A missing visual mesh is a warning naming every path tried; the visual shows the collision box."""
    sdf = tmp_path / "m.sdf"
    sdf.write_text("""<sdf version='1.9'><model name='m'><link name='l'>
      <collision name='c'><pose>0 0 0.5 0 0 0</pose><geometry><box><size>1 2 3</size></box></geometry></collision>
      <collision name='gone'><geometry><mesh><uri>gone.stl</uri></mesh></geometry></collision>
      <visual name='v'><geometry><mesh><uri>meshes/body.stl</uri></mesh></geometry></visual></link></model></sdf>""")
    caplog.set_level(logging.WARNING)
    link = load_model(sdf).links[0]
    assert [c.name for c in link.collisions] == ["c"]
    (visual,) = link.visuals
    assert visual.name == "v" and visual.geometry == link.collisions[0].geometry and visual.pose.xyz == (0, 0, 0.5)
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2
    assert (
        str(tmp_path / "meshes" / "body.stl") in messages[1]
        and str(asset("worlds/models") / "meshes" / "body.stl") in messages[1]
    )
