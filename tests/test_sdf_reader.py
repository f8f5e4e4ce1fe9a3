"""SDF frame semantics and parsing on small files written for each case."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from probe_helpers import PROBE, WORLD, load

from simbot.description import DescriptionError, load_model, load_sdf, load_world
from simbot.description.model import Atmosphere, Model, SphericalCoordinates

LINK = "<link name='{name}'>{body}</link>"


def _model(tmp_path: Path, body: str, version: str = "1.9") -> Path:
    path = tmp_path / "model.sdf"
    path.write_text(f"<sdf version='{version}'><model name='m'>{body}</model></sdf>")
    return path


def test_relative_to_chains_links_joints_and_frames(tmp_path: Path) -> None:
    """A link placed relative to a joint, which sits in its child's frame, via an explicit <frame>."""
    sdf = _model(
        tmp_path,
        """
      <frame name='mount' attached_to='a'><pose>0 0 1 0 0 0</pose></frame>
      <link name='a'><pose>1 0 0 0 0 1.5707963267948966</pose></link>
      <link name='b'><pose relative_to='mount'>1 0 0 0 0 0</pose></link>
      <link name='c'><pose relative_to='j'>0 0 0.5 0 0 0</pose></link>
      <joint name='j' type='fixed'><pose>0 2 0 0 0 0</pose><parent>a</parent><child>b</child></joint>
      <joint name='k' type='fixed'><parent>a</parent><child>c</child></joint>""",
    )
    model = load_model(sdf)
    # mount = a ∘ (0 0 1) = (1, 0, 1) yawed 90°; b = mount ∘ (1 0 0) = (1, 1, 1)
    assert np.allclose(model.link("b").pose.xyz, (1, 1, 1))
    # j sits in b's frame: b ∘ (0 2 0) = (1 - 2, 1, 1); c = j ∘ (0 0 0.5)
    assert np.allclose(model.joint("j").pose.xyz, (-1, 1, 1))
    assert np.allclose(model.link("c").pose.xyz, (-1, 1, 1.5))
    assert model.link("c").pose.rpy[2] == pytest.approx(math.pi / 2)


def test_shapes_and_sensors_relative_to_other_frames(tmp_path: Path) -> None:
    """A collision placed relative to another link is re-expressed in its own link's frame."""
    sdf = _model(
        tmp_path,
        """
      <link name='a'><pose>1 0 0 0 0 0</pose>
        <collision name='c'><pose relative_to='b'>0 0 0 0 0 0</pose><geometry><sphere><radius>0.1</radius></sphere></geometry></collision>
        <sensor name='s' type='imu'><pose relative_to='__model__'>0 0 2 0 0 0</pose></sensor></link>
      <link name='b'><pose>0 3 0 0 0 0</pose></link>""",
    )
    link = load_model(sdf).link("a")
    assert np.allclose(link.collisions[0].pose.xyz, (-1, 3, 0))
    assert np.allclose(link.sensors[0].pose.xyz, (-1, 0, 2))


def test_axis_expressed_in_and_sdf_16_conventions(tmp_path: Path) -> None:
    """Axis xyz is in the joint frame; expressed_in and SDF 1.6's use_parent_model_frame convert it."""
    joint = """<link name='a'/><link name='b'><pose>0 0 0 0 0 1.5707963267948966</pose></link>
      <joint name='j' type='revolute'><parent>a</parent><child>b</child><axis>{xyz}{extra}</axis></joint>"""
    in_joint = load_model(_model(tmp_path, joint.format(xyz="<xyz>1 0 0</xyz>", extra=""))).joint("j").axis
    assert in_joint is not None and np.allclose(in_joint.xyz, (1, 0, 0))
    in_model = (
        load_model(_model(tmp_path, joint.format(xyz="<xyz expressed_in='__model__'>1 0 0</xyz>", extra="")))
        .joint("j")
        .axis
    )
    assert in_model is not None and np.allclose(in_model.xyz, (0, -1, 0))
    old = joint.format(xyz="<xyz>1 0 0</xyz>", extra="<use_parent_model_frame>true</use_parent_model_frame>")
    legacy = (
        load_model(_model(tmp_path, old.replace("<link name='a'/>", "<link name='a'></link>"), version="1.6"))
        .joint("j")
        .axis
    )
    assert legacy is not None and np.allclose(legacy.xyz, (0, -1, 0))


def test_pose_formats(tmp_path: Path) -> None:
    """Degrees, quaternions and the SDF 1.6 `frame` attribute are all read."""
    sdf = _model(
        tmp_path,
        """
      <link name='a'><pose degrees='true'>0 0 0 0 0 90</pose></link>
      <link name='b'><pose rotation_format='quat_xyzw'>1 2 3 0 0 0.7071067811865476 0.7071067811865476</pose></link>
      <link name='c'><pose frame='b'>1 0 0 0 0 0</pose></link>""",
        version="1.9",
    )
    model = load_model(sdf)
    assert model.link("a").pose.rpy[2] == pytest.approx(math.pi / 2)
    assert model.link("b").pose.rpy[2] == pytest.approx(math.pi / 2)
    assert np.allclose(model.link("c").pose.xyz, (1, 3, 3))


def test_limits_plugins_and_materials(tmp_path: Path) -> None:
    """Joint limits (±1e16 means none), plugin parameters in order and nested, colours."""
    sdf = _model(
        tmp_path,
        """
      <link name='a'><visual name='v'><geometry><box><size>1 1 1</size></box></geometry>
        <material><ambient>1 0 0 1</ambient><diffuse>0 1 0</diffuse></material></visual></link>
      <link name='b'/>
      <joint name='j' type='prismatic'><parent>a</parent><child>b</child>
        <axis><xyz>0 0 2</xyz><limit><lower>-0.5</lower><upper>1e16</upper><effort>7</effort></limit>
        <dynamics><damping>0.3</damping></dynamics></axis></joint>
      <plugin name='P' filename='libp.so'><x>1</x><x>2</x><out type='T' topic='/t'><y>3</y></out></plugin>""",
    )
    model = load_model(sdf)
    axis = model.joint("j").axis
    assert axis is not None and axis.xyz == (0, 0, 1) and (axis.lower, axis.upper, axis.effort) == (-0.5, None, 7)
    assert axis.velocity is None and axis.damping == 0.3
    (plugin,) = model.plugins
    assert plugin.get_all("x") == ["1", "2"] and plugin.get("missing") is None
    out = plugin.params[2]
    assert dict(out.attrs) == {"type": "T", "topic": "/t"} and out.children[0].text == "3"
    material = model.link("a").visuals[0].material
    assert material is not None and material.color() == (0, 1, 0, 1)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("<link name='a'><pose relative_to='b'/></link><link name='b'><pose relative_to='a'/></link>", "cycle"),
        ("<link name='a'/><link name='a'/>", "duplicate frame name 'a'"),
        (
            "<link name='a'/><joint name='j' type='universal'><parent>a</parent><child>a</child></joint>",
            "unsupported joint type",
        ),
        (
            "<link name='a'/><joint name='j' type='fixed'><parent>a</parent><child>z</child></joint>",
            "child 'z' is not a link",
        ),
        (
            "<link name='a'/><link name='b'/><joint name='j' type='revolute'><parent>a</parent><child>b</child></joint>",
            "needs an <axis>",
        ),
        ("<link name='a'><inertial><mass>-1</mass></inertial></link>", "mass must be positive"),
        ("<link name='a'><pose>1 2 3</pose></link>", "expected 6 numbers"),
    ],
)
def test_model_errors(tmp_path: Path, body: str, message: str) -> None:
    """Each mistake names itself, the file and the line."""
    sdf = _model(tmp_path, body)
    with pytest.raises(DescriptionError, match=message) as error:
        load_model(sdf)
    assert error.value.file == str(sdf) and error.value.line == 1


def test_world_include_with_overrides(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """<include> resolves model:// through model.config, picks its newest SDF, and applies name, pose, static."""
    folder = tmp_path / "models" / "crate"
    folder.mkdir(parents=True)
    (folder / "model.config").write_text(
        "<model><sdf version='1.6'>old.sdf</sdf><sdf version='1.9'>model.sdf</sdf></model>"
    )
    (folder / "model.sdf").write_text(
        "<sdf version='1.9'><model name='crate'><link name='l'><inertial><mass>2</mass></inertial></link></model></sdf>"
    )
    monkeypatch.setenv("SIMBOT_RESOURCE_PATH", str(tmp_path / "models"))
    world_file = tmp_path / "w.sdf"
    world_file.write_text("""<sdf version='1.9'><world name='w'><gravity>0 0 -3.7</gravity>
      <physics name='slow' type='ode'><max_step_size>0.004</max_step_size></physics>
      <light name='sun' type='directional'><direction>0 0 -1</direction></light>
      <include><uri>model://crate</uri><name>crate_7</name><pose>1 2 3 0 0 0</pose><static>true</static></include>
      </world></sdf>""")
    world = load_world(world_file)
    crate = world.model("crate_7")
    assert crate.pose.xyz == (1, 2, 3) and crate.static and crate.links[0].inertial.mass == 2  # type: ignore[union-attr]
    assert (
        world.gravity == (0, 0, -3.7) and world.physics.max_step_size == 0.004 and world.lights[0].type == "directional"
    )


def test_world_earth_magnetic_field_and_atmosphere_are_read(tmp_path: Path) -> None:
    """`<spherical_coordinates>`, `<magnetic_field>` and `<atmosphere>` into the World; SDF's defaults
    where a world leaves them out; a world frame other than ENU is an error naming the file."""
    world = (
        "<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><world_frame_orientation>ENU"
        "</world_frame_orientation><latitude_deg>-33.9</latitude_deg><longitude_deg>151.2</longitude_deg>"
        "<elevation>58</elevation><heading_deg>12.5</heading_deg></spherical_coordinates>"
        "<magnetic_field>1e-6 2e-6 -3e-6</magnetic_field>"
        '<atmosphere type="adiabatic"><temperature>300</temperature><pressure>100000</pressure>'
        "<temperature_gradient>-0.005</temperature_gradient></atmosphere>"
    )
    given, bare = tmp_path / "given.sdf", tmp_path / "bare.sdf"
    given.write_text(WORLD.format(world=world))
    bare.write_text(WORLD.format(world=""))
    read, default = load_world(given), load_world(bare)
    assert read.spherical_coordinates == SphericalCoordinates("EARTH_WGS84", "ENU", -33.9, 151.2, 58.0, 12.5)
    assert read.magnetic_field == (1e-6, 2e-6, -3e-6)
    assert read.atmosphere == Atmosphere(300.0, 100000.0, -0.005)
    assert default.spherical_coordinates == SphericalCoordinates()
    assert default.magnetic_field == (5.5645e-6, 22.8758e-6, -42.3884e-6)
    assert default.atmosphere == Atmosphere(288.15, 101325.0, -0.0065)
    ned = tmp_path / "ned.sdf"
    ned.write_text(
        WORLD.format(
            world="<spherical_coordinates><world_frame_orientation>NED</world_frame_orientation></spherical_coordinates>"
        )
    )
    with pytest.raises(DescriptionError, match="world_frame_orientation 'NED' is not supported"):
        load_world(ned)


def test_a_joints_sensor_is_posed_from_the_joint_on_its_child_link(tmp_path: Path) -> None:
    """A `<sensor>` in a `<joint>` is the joint's (`joint_of`), listed with the joint's child link, its
    pose relative to the joint frame by default (SDF), kept in the child link's frame."""
    extra = (
        load("held", 0.5, "")
        .replace("<child>held</child>", "<child>held</child><pose>0.1 0 0 0 0 0</pose>")
        .replace('type="force_torque"><pose>0 0 0 0 0 0</pose>', 'type="force_torque"><pose>0 0 0.2 0 0 0</pose>')
    )
    robot = tmp_path / "probe.sdf"
    robot.write_text(PROBE.format(static="true", mass=1.0, sensors="", extra=extra))
    model = load_sdf(robot)
    assert isinstance(model, Model)
    ((link, held),) = model.sensors()
    assert (link.name, held.type, model.joint_of(held)) == ("held", "force_torque", model.joint("held_joint"))
    assert held.pose.xyz == pytest.approx((0.1, 0.0, 0.2))
