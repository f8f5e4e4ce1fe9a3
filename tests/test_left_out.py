"""Nothing dropped in silence (issue 37): a sensor whose SDF parameters are bad is left out of a
real server's world, and said so in world state (`systems_left_out`), in `simbot describe` of the
file (checked by the server's own code, with no server running) and in `simbot monitor`; the
rest of the world runs.

One lockstep server for the module, of a world written here: a static scanner with two planar
lidars, one of them with `<range><min>` above `<max>`. World state's entries are about the SDF:
a reset keeps them, and a model created at run time takes its own with it when it leaves.
Without a server, describe's check (`left_out_of`) finds other kinds of bad parameters (a
camera's, a plugin's, a visual's plugin's, a stated priority) and nothing in the good SDF of every
registered system (`test_conformance.py`'s, which a server runs whole).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from client_helpers import client_process
from conftest import ROBOT_SDF, run_cli
from server_helpers import SimServer, running_server, wait_until
from test_conformance import CASES, ROBOT
from test_conformance import WORLD as CONFORMANCE_WORLD

from simbot.description import load_description
from simbot.sim.loop.sdf_systems import left_out_of

LASER_SCAN = "sensor_msgs/msg/LaserScan"
MONITOR_TIMEOUT_S = 60.0
BAD = {
    "name": "scanner/base/lidar_bad",
    "kind": "gpu_lidar",
    "reason": "sensor lidar_bad: <range> needs 0 ≤ min < max, got min 5.0 max 1.0",
}
"""The scanner's lidar whose range starts beyond where it ends."""
CREATED_BAD = {
    "name": "extra/body/lidar_worse",
    "kind": "gpu_lidar",
    "reason": "sensor lidar_worse: <range> needs 0 ≤ min < max, got min 0.0 max -1.0",
}
"""The lidar of a model created at run time, its range ending before zero."""
NO_LEFT_OUT = "systems left out (bad SDF parameters: a server runs without them): none"


def lidar(name: str, low: float, high: float) -> str:
    """A planar lidar of 8 rays at 10 Hz on the key `name`, its range from `low` to `high`."""
    return (
        f'<sensor name="{name}" type="gpu_lidar"><update_rate>10</update_rate><topic>{name}</topic>'
        "<lidar><scan><horizontal><samples>8</samples><min_angle>-0.5</min_angle><max_angle>0.5</max_angle>"
        f"</horizontal></scan><range><min>{low}</min><max>{high}</max></range></lidar></sensor>"
    )


WORLD = f"""<?xml version="1.0"?>
<sdf version="1.10">
  <world name="left_out">
    <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="c"><geometry><plane><normal>0 0 1</normal><size>20 20</size></plane></geometry></collision>
      </link>
    </model>
    <model name="scanner">
      <static>true</static>
      <pose>0 0 0.5 0 0 0</pose>
      <link name="base">
        <collision name="c"><geometry><box><size>0.2 0.2 0.2</size></box></geometry></collision>
        {lidar("lidar_good", 0.1, 10.0)}
        {lidar("lidar_bad", 5.0, 1.0)}
      </link>
    </model>
  </world>
</sdf>
"""

CREATED = f"""<?xml version="1.0"?>
<sdf version="1.10">
  <model name="extra">
    <static>true</static>
    <link name="body">
      <collision name="c"><geometry><box><size>0.2 0.2 0.2</size></box></geometry></collision>
      {lidar("lidar_worse", 0.0, -1.0)}
    </link>
  </model>
</sdf>
"""


@pytest.fixture(scope="module", name="files")
def files_fixture(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The world and the model to create, as files."""
    folder = tmp_path_factory.mktemp("left_out")
    paths = {"world": folder / "left_out.sdf", "created": folder / "extra.sdf"}
    paths["world"].write_text(WORLD)
    paths["created"].write_text(CREATED)
    return paths


@pytest.fixture(scope="module", name="sim")
def sim_fixture(files: dict[str, Path]) -> Iterator[SimServer]:
    with running_server(str(files["world"]), "lockstep", extra=("--robot", "none")) as server:
        yield server


def test_world_state_lists_the_lidar_left_out_and_the_other_one_publishes(sim: SimServer) -> None:
    """Its entry names the lidar, its type and the element; the server logged it once; the good lidar scans."""
    state = sim.state()
    assert state["systems_left_out"] == [BAD]
    assert set(state["sensors"]) == {"scanner/base/lidar_good"}
    assert [line for line in sim.errors() if "lidar_bad" in line] == [
        f"ERROR simbot.sim.loop.world: {BAD['reason']}; the world runs without it"
    ]
    scan = sim.latest({"lidar_good": LASER_SCAN}, chunk=100)["lidar_good"]
    assert (len(scan.ranges), scan.range_min, scan.range_max) == (8, pytest.approx(0.1), pytest.approx(10.0))


def test_a_reset_keeps_the_entries_and_a_created_model_takes_its_own_along(
    sim: SimServer, files: dict[str, Path]
) -> None:
    """Created at run time, a model's lidar left out is listed after the world's; the reset removes
    the model, and its entry with it, and keeps the world's."""
    reply = sim.call("create", {"sdf_filename": str(files["created"]), "pose": {"position": {"x": 3.0}}})
    assert reply == {"ok": True, "name": "extra"}
    assert sim.state()["systems_left_out"] == [BAD, CREATED_BAD]
    sim.reset()
    state = sim.state()
    assert "extra" not in state["models"] and state["systems_left_out"] == [BAD]


def test_describe_lists_what_a_server_would_leave_out(files: dict[str, Path]) -> None:
    """describe of the world and of the model names each bad lidar with its kind and reason, exit 0;
    the shipped robot has none."""
    for path, entry in ((files["world"], BAD), (files["created"], CREATED_BAD)):
        result = run_cli("describe", str(path))
        assert result.returncode == 0, result.stderr
        assert "systems left out (bad SDF parameters: a server runs without them) (1)" in result.stdout
        row = rf"^{re.escape(entry['name'])}\s+{entry['kind']}\s+{re.escape(entry['reason'])}$"
        assert re.search(row, result.stdout, re.MULTILINE), result.stdout
    robot = run_cli("describe", str(ROBOT_SDF))
    assert robot.returncode == 0 and NO_LEFT_OUT in robot.stdout.splitlines(), robot.stdout[-2000:]


def test_monitor_shows_the_lidar_left_out(sim: SimServer) -> None:
    """A row of its own: the lidar's scoped name, `left out`, and why."""
    row = re.compile(rf"^{re.escape(BAD['name'])}\s+left out  {re.escape(BAD['reason'])}$", re.MULTILINE)
    with client_process(sim, "monitor", "--period", "0.3") as monitor:
        wait_until(lambda: row.search(monitor.stdout()), MONITOR_TIMEOUT_S, "the monitor's row of the lidar left out")
        assert monitor.alive(), monitor.stderr()


PROBE = """<?xml version="1.0"?>
<sdf version="1.10">
  <model name="probe">
    <static>true</static>
    <link name="body">
      <collision name="c"><geometry><box><size>0.2 0.2 0.2</size></box></geometry></collision>
      <visual name="v"><geometry><box><size>0.2 0.2 0.2</size></box></geometry>{visual}</visual>
      {sensors}
    </link>
    {plugins}
  </model>
</sdf>
"""
ODOMETRY = '<plugin name="gz::sim::systems::OdometryPublisher" filename="gz-sim-odometry-publisher-system">{}</plugin>'
BAD_PARAMETERS = {
    "camera": (
        {"sensors": '<sensor name="cam" type="camera"><camera><image><width>0</width></image></camera></sensor>'},
        ("probe/body/cam", "camera", "sensor cam: <camera><image><width> must be 1..8192 pixels, got 0"),
    ),
    "plugin": (
        {"plugins": ODOMETRY.format("<dimensions>4</dimensions>")},
        (
            "probe/gz::sim::systems::OdometryPublisher",
            "gz-sim-odometry-publisher-system",
            "gz::sim::systems::OdometryPublisher: <dimensions> must be 2 or 3, got 4",
        ),
    ),
    "priority": (
        {"plugins": ODOMETRY.format("<gz:system_priority>soon</gz:system_priority>")},
        (
            "probe/gz::sim::systems::OdometryPublisher",
            "gz-sim-odometry-publisher-system",
            "gz::sim::systems::OdometryPublisher: <gz:system_priority> expected an integer, got 'soon'",
        ),
    ),
    "visual": (
        {"visual": '<plugin name="gz::sim::systems::Label" filename="gz-sim-label-system"><label>300</label></plugin>'},
        (
            "probe/body/v/gz::sim::systems::Label",
            "gz-sim-label-system",
            "Label on probe visual v: <label> must be 0..255, got 300",
        ),
    ),
}
"""A probe model's parts with one bad parameter each, and what describe says of it: (name, kind, reason)."""


@pytest.mark.parametrize("case", sorted(BAD_PARAMETERS))
def test_describe_names_each_kind_of_system_left_out(case: str, tmp_path: Path) -> None:
    parts, expected = BAD_PARAMETERS[case]
    probe = tmp_path / "probe.sdf"
    probe.write_text(PROBE.format(**({"visual": "", "sensors": "", "plugins": ""} | parts)))
    assert [(e.name, e.kind, e.reason) for e in left_out_of(load_description(probe))] == [expected]


def test_describe_leaves_nothing_out_of_a_good_sdf_of_any_system(tmp_path: Path) -> None:
    """Each registered system's conformance world and robot, which a server runs with every system."""
    for (group, name), case in CASES.items():
        world, robot = tmp_path / f"{group}.{name}.world.sdf", tmp_path / f"{group}.{name}.robot.sdf"
        world.write_text(CONFORMANCE_WORLD.format(world_plugins=case.world_plugins))
        robot.write_text(ROBOT.format(plugins=case.plugins, sensors=case.sensors))
        assert left_out_of(load_description(world)) == [], name
        assert left_out_of(load_description(robot)) == [], name
