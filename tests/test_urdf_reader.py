"""URDF and xacro input: expanded with xacro, validated by yourdfpy, walked into a Model."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOT_SDF, ROBOT_URDF, run_cli

from simbot.description import DescriptionError, Model, load_description, load_model, model_to_urdf
from simbot.description.model import Cylinder
from simbot.description.urdf_writer import link_frame

XACRO = Path(__file__).parent / "fixtures" / "two_wheels.urdf.xacro"


def test_xacro_is_expanded() -> None:
    """Macros and properties expand: two wheels at ±track/2 with the property's radius."""
    model = load_description(XACRO)
    assert isinstance(model, Model)
    assert model.name == "two_wheels" and [link.name for link in model.links] == [
        "base_link",
        "left_wheel",
        "right_wheel",
    ]
    left = model.link("left_wheel")
    assert np.allclose(left.pose.xyz, (0, 0.25, -0.05)) and np.allclose(
        model.link("right_wheel").pose.xyz, (0, -0.25, -0.05)
    )
    visual = left.visuals[0]
    assert isinstance(visual.geometry, Cylinder) and visual.geometry.radius == 0.1
    assert visual.pose.rpy[0] == pytest.approx(math.pi / 2) and visual.material is not None
    joint = model.joint("left_wheel_joint")
    assert joint.type == "continuous" and joint.axis is not None and joint.axis.xyz == (0, 1, 0)


def test_describe_takes_xacro() -> None:
    """`simbot describe` accepts a xacro file wherever a URDF is accepted."""
    result = run_cli("describe", str(XACRO))
    assert result.returncode == 0, result.stderr
    assert "links (3)" in result.stdout and "left_wheel_joint" in result.stdout


def test_generated_urdf_reads_back_as_the_sdf() -> None:
    """Our URDF, read back, puts every link frame where the writer said (forward kinematics by yourdfpy)."""
    sdf = load_model(ROBOT_SDF)
    urdf = load_description(ROBOT_URDF)
    assert isinstance(urdf, Model)
    for link in sdf.links:
        assert np.allclose(urdf.link(link.name).pose.matrix(), link_frame(link).matrix(), atol=1e-9), link.name
    assert urdf.link("base_link").inertial.mass == 100  # type: ignore[union-attr]
    assert model_to_urdf(urdf)  # and it converts again


def test_bad_xacro_and_urdf(tmp_path: Path) -> None:
    """A xacro error or an invalid URDF is a DescriptionError naming the file."""
    broken = tmp_path / "broken.urdf.xacro"
    broken.write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r"><link name="${undefined_property}"/></robot>'
    )
    with pytest.raises(DescriptionError, match="xacro") as error:
        load_description(broken)
    assert error.value.file == str(broken)
    invalid = tmp_path / "invalid.urdf"
    invalid.write_text(
        '<robot name="r"><link name="a"/><joint name="j" type="hinge"><parent link="a"/><child link="a"/></joint></robot>'
    )
    with pytest.raises(DescriptionError, match="invalid URDF"):
        load_description(invalid)
    result = run_cli("describe", str(broken))
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
