"""SDF → URDF: every link, collision and visual keeps its world pose (yourdfpy forward kinematics)."""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from conftest import REFERENCE, ROBOT_SDF, ROBOT_URDF, TROLLEY_SDF
from golden_helpers import Tolerance, text_differences

from simbot.description import Model, load_model, model_to_urdf
from simbot.description.model import Plane
from simbot.description.urdf_writer import link_frame

POSE_TOL = 1e-6


def _write(model: Model, folder: Path) -> yourdfpy.URDF:
    path = folder / f"{model.name}.urdf"
    path.write_text(model_to_urdf(model, folder))
    urdf = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    assert urdf.validate(), f"yourdfpy rejects the URDF of {model.name}"
    return urdf


def _origin(element: yourdfpy.Visual | yourdfpy.Collision) -> np.ndarray:
    return np.eye(4) if element.origin is None else element.origin


def _models() -> list[pytest.ParameterSet]:
    reference = REFERENCE / "urdf" / "Flexley_Tug.sdf"
    skip = pytest.mark.skipif(not reference.is_file(), reason=f"reference description not found at {reference}")
    return [
        pytest.param(ROBOT_SDF, id="flexley_tug"),
        pytest.param(TROLLEY_SDF, id="trolley"),
        pytest.param(reference, id="reference_Flexley_Tug", marks=skip),
    ]


@pytest.mark.parametrize("sdf", _models())
def test_world_poses_survive_conversion(sdf: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """For each link, collision and visual, URDF forward kinematics equals the SDF pose within 1e-6."""
    caplog.set_level(logging.ERROR)
    model = load_model(sdf)
    urdf = _write(model, tmp_path)
    root = link_frame(model.link(urdf.base_link)).matrix()
    checked = 0
    for link in model.links:
        world = root @ urdf.get_transform(link.name, urdf.base_link)
        assert np.abs(world - link_frame(link).matrix()).max() < POSE_TOL, link.name
        urdf_link = urdf.link_map[link.name]
        pairs = list(zip(link.collisions, urdf_link.collisions)) + list(zip(link.visuals, urdf_link.visuals))
        assert len(pairs) == len(link.collisions) + len(link.visuals) and len(urdf_link.visuals) == len(link.visuals)
        for sdf_shape, urdf_shape in pairs:
            assert sdf_shape.name == urdf_shape.name
            expected = link.pose.matrix() @ sdf_shape.pose.matrix()
            assert np.abs(world @ _origin(urdf_shape) - expected).max() < POSE_TOL, f"{link.name}/{sdf_shape.name}"
            checked += 1
    assert checked >= len(model.links)


PRINTED = Tolerance(
    1e-11,
    1e-12,
    "the writer prints 12 significant digits of a value rounded to 12 decimals: a CPU's last bit "
    "can flip the last digit printed, 1e-11 relative, 1e-12 absolute near zero",
)


def test_committed_urdf_is_up_to_date() -> None:
    """urdf/flexley_tug.urdf is what `simbot sdf2urdf` makes of urdf/flexley_tug.sdf (`make urdf`):
    the same text, its numbers to the digits printed."""
    expected = model_to_urdf(load_model(ROBOT_SDF), ROBOT_URDF.parent)
    found = text_differences(expected, ROBOT_URDF.read_text(), PRINTED)
    assert not found, "run `make urdf` and commit urdf/flexley_tug.urdf: " + "; ".join(found)


def test_masses_and_joints(tmp_path: Path) -> None:
    """Masses carry over, massless links say so, the root gets its token mass, ball joints become three."""
    model = load_model(ROBOT_SDF)
    urdf = _write(model, tmp_path)
    for link in model.links[1:]:
        expected = link.inertial.mass if link.inertial else 0.0
        assert urdf.link_map[link.name].inertial.mass == pytest.approx(expected)
    assert 0 < urdf.link_map["base_footprint"].inertial.mass <= 1e-3
    swivel = [j for j in urdf.robot.joints if j.name.startswith("castor_front_left_joint")]
    assert sorted(j.type for j in swivel) == ["continuous"] * 3
    axes = sorted(tuple(np.abs(j.axis)) for j in swivel)
    assert axes == [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)]
    wheel = urdf.joint_map["front_left_wheel_joint"]
    assert wheel.type == "continuous" and wheel.child == "front_left_wheel" and wheel.limit.effort == 10000


def test_offset_joint_gets_a_frame_link(tmp_path: Path) -> None:
    """A revolute joint away from its child's origin turns about the joint, not the link origin."""
    sdf = tmp_path / "arm.sdf"
    sdf.write_text("""<sdf version="1.9"><model name="arm">
      <link name="base"><inertial><mass>1</mass></inertial></link>
      <link name="arm"><inertial><mass>1</mass></inertial></link>
      <joint name="hinge" type="revolute"><pose>0.5 0 0 0 0 0</pose><parent>base</parent><child>arm</child>
        <axis><xyz>0 0 1</xyz><limit><lower>-1</lower><upper>1</upper></limit></axis></joint>
    </model></sdf>""")
    urdf = _write(load_model(sdf), tmp_path)
    assert urdf.joint_map["hinge"].child == "hinge__frame"
    assert urdf.joint_map["hinge"].limit.lower == -1 and urdf.joint_map["hinge"].limit.upper == 1
    urdf.update_cfg({"hinge": np.pi / 2})
    arm_origin = urdf.get_transform("arm", "base")[:3, 3]
    assert np.allclose(arm_origin, (0.5, -0.5, 0.0))  # the link origin swung about the hinge at x 0.5


def test_plane_becomes_a_box_with_its_top_on_the_plane(tmp_path: Path) -> None:
    """URDF has no plane: the thin box that stands in has its top face on the SDF plane."""
    sdf = tmp_path / "ground.sdf"
    sdf.write_text("""<sdf version="1.7"><model name="ground"><static>true</static><link name="link">
      <collision name="c"><geometry><plane><normal>0 0 1</normal><size>50 40</size></plane></geometry></collision>
    </link></model></sdf>""")
    model = load_model(sdf)
    assert isinstance(model.links[0].collisions[0].geometry, Plane)
    urdf = _write(model, tmp_path)
    box = urdf.link_map["link"].collisions[0]
    top = box.origin[2, 3] + box.geometry.box.size[2] / 2
    assert tuple(box.geometry.box.size[:2]) == (50, 40) and top == pytest.approx(0.0, abs=1e-12)


def test_a_link_that_names_its_sensor_frame_has_its_urdf_frame_at_the_sensor(tmp_path: Path) -> None:
    """The lidar links: the URDF frame (what tf publishes) is the sensor's, and the body stays put."""
    model = load_model(ROBOT_SDF)
    urdf = _write(model, tmp_path)
    for name, (x, yaw) in {"base_scan_front": (0.99, 0.0), "base_scan_back": (-0.95, math.pi)}.items():
        frame = urdf.get_transform(name, urdf.base_link)
        assert np.allclose(frame[:3, 3], (x, 0.0, 0.26), atol=1e-9), name
        assert math.isclose(math.atan2(frame[1, 0], frame[0, 0]) % (2 * math.pi), yaw % (2 * math.pi), abs_tol=1e-9), (
            name
        )
        cylinder = frame @ _origin(urdf.link_map[name].collisions[0])
        sdf_link = model.link(name)
        assert np.allclose(cylinder, sdf_link.pose.matrix() @ sdf_link.collisions[0].pose.matrix(), atol=1e-9), name


def test_a_fleets_tugs_share_one_writing_of_their_model_and_a_changed_model_is_written_anew() -> None:
    """A thousand tugs are one Model object: its URDF is written once (simbot.description.model_memo)
    and handed to each; an equal model read again, or one changed, is written for itself."""
    tug = load_model(ROBOT_SDF)
    first = model_to_urdf(tug, mesh_uris=True)
    assert model_to_urdf(tug, mesh_uris=True) is first
    assert model_to_urdf(tug) is not first, "other arguments: another writing"
    again = load_model(ROBOT_SDF)
    assert again is not tug and model_to_urdf(again, mesh_uris=True) == first
    other = dataclasses.replace(tug, name="tug_other")
    assert '<robot name="tug_other">' in model_to_urdf(other, mesh_uris=True)
    assert '<robot name="tug_other">' not in first
