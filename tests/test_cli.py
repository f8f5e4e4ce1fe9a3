"""`simbot sdf2urdf` and `simbot describe` as a user runs them, and one line with exit 2 for bad input."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yourdfpy
from conftest import REPO, ROBOT_SDF, run_cli

GOOD_LINK = '<link name="a"><inertial><mass>1</mass></inertial></link>'


def test_sdf2urdf_writes_a_valid_urdf(tmp_path: Path) -> None:
    """-o writes a URDF that yourdfpy validates, with mesh paths relative to it."""
    out = tmp_path / "robot.urdf"
    result = run_cli("sdf2urdf", str(ROBOT_SDF), "-o", str(out))
    assert result.returncode == 0, result.stderr
    urdf = yourdfpy.URDF.load(str(out), load_meshes=False)
    assert urdf.validate() and len(urdf.link_map) == 13 + 4 * 2  # + two gimbal links per castor
    meshes = re.findall(r'filename="([^"]+)"', out.read_text())
    assert meshes and all((out.parent / m).resolve().is_file() for m in meshes)


def test_sdf2urdf_to_stdout() -> None:
    """Without -o the URDF goes to standard output."""
    result = run_cli("sdf2urdf", str(ROBOT_SDF))
    assert (
        result.returncode == 0 and result.stdout.startswith("<?xml") and '<robot name="flexley_tug">' in result.stdout
    )


def test_describe_tables() -> None:
    """describe lists links, joints, sensors and plugins of the robot."""
    result = run_cli("describe", str(ROBOT_SDF))
    assert result.returncode == 0, result.stderr
    for heading in ("links (13)", "joints (12)", "sensors (9)", "plugins (3)"):
        assert heading in result.stdout
    assert "lidar_front" in result.stdout and "gz::sim::systems::DiffDrive" in result.stdout


def test_describe_world() -> None:
    """describe of the warehouse lists its models, the trolley among them."""
    result = run_cli("describe", str(REPO / "worlds" / "warehouse.sdf"))
    assert result.returncode == 0, result.stderr
    assert re.search(r"^trolley\s+1 0.2 0", result.stdout, re.MULTILINE)


BAD_INPUTS = {
    "malformed_xml": ("<sdf version='1.9'><model name='m'>\n<link name='a'>\n</model></sdf>", "malformed XML", 3),
    "missing_element": (
        "<sdf version='1.9'><model name='m'>\n<link name='a'><collision name='c'>\n<geometry><mesh/></geometry>\n</collision></link></model></sdf>",
        "missing required element <uri>",
        3,
    ),
    "missing_attribute": (
        "<sdf version='1.9'>\n<model>" + GOOD_LINK + "</model></sdf>",
        "missing required attribute 'name'",
        2,
    ),
    "unsupported_version": (
        "<sdf version='2.0'><model name='m'>" + GOOD_LINK + "</model></sdf>",
        "unsupported SDF version 2.0",
        1,
    ),
    "unresolvable_include": (
        "<sdf version='1.9'><world name='w'>\n<include>\n<uri>model://no_such_model</uri></include></world></sdf>",
        "cannot resolve 'model://no_such_model'",
        3,
    ),
    "bad_number": (
        "<sdf version='1.9'><model name='m'><link name='a'><inertial>\n<mass>heavy</mass></inertial></link></model></sdf>",
        "expected numbers, got 'heavy'",
        2,
    ),
    "malformed_after_gazebo_comment": (
        "<sdf version='1.9'><!-- gz sim --verbose -->\n<model name='m'>\n<link name='a'>\n</model></sdf>",
        "malformed XML",
        4,
    ),
    "unknown_frame": (
        "<sdf version='1.9'><model name='m'>\n<link name='a'><pose relative_to='nowhere'>0 0 0 0 0 0</pose></link></model></sdf>",
        "unknown frame 'nowhere'",
        2,
    ),
}


CASES = [(case, "describe") for case in sorted(BAD_INPUTS)]
CASES += [(case, "sdf2urdf") for case in sorted(BAD_INPUTS) if case != "unresolvable_include"]  # a world, not a model


@pytest.mark.parametrize(("case", "command"), CASES)
def test_bad_input_is_one_line_and_exit_2(case: str, command: str, tmp_path: Path) -> None:
    """Each kind of bad input: exit 2, one line naming the file, the line and the problem; no traceback."""
    text, message, line = BAD_INPUTS[case]
    bad = tmp_path / f"{case}.sdf"
    bad.write_text(text)
    result = run_cli(command, str(bad))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert f"{bad}:{line}:" in lines[0] and message in lines[0]


def test_missing_file_and_usage(tmp_path: Path) -> None:
    """A file that does not exist, and a command line that makes no sense, also exit 2."""
    result = run_cli("describe", str(tmp_path / "nope.sdf"))
    assert result.returncode == 2 and "nope.sdf" in result.stderr and "no such file" in result.stderr
    assert run_cli("frobnicate").returncode == 2


@pytest.mark.parametrize(
    "command", ["teleop", "merger", "stitcher", "dock", "topics", "echo", "monitor", "snapshot", "launch"]
)
def test_simbot_runs_each_client_with_the_rest_of_the_line(command: str) -> None:
    """`simbot CLIENT ARGS` is the client's own command line: its --help, and its one-line usage errors."""
    helped = run_cli(command, "--help")
    assert helped.returncode == 0 and "--namespace" in helped.stdout and "--connect" in helped.stdout, helped.stderr
    wrong = run_cli(command, "--no-such-option")
    last = wrong.stderr.strip().splitlines()[-1]
    assert wrong.returncode == 2 and ": error: " in last and "Traceback" not in wrong.stderr, wrong.stderr
