"""``hier-ssl deploy`` and ``hier-ssl field`` as processes over 127.0.0.1: a signal stops every robot
before exit, the field server publishes vision, bad options end with one line naming them."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hier_ssl import cli
from hier_ssl.deploy import wire
from hier_ssl.deploy.assemble import parse_robots, parse_targets
from hier_ssl.deploy.net import command_target, open_vision, parse_address

ROOT = Path(__file__).parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _frame(t: float) -> bytes:
    return wire.encode_detection(0, wire.DetectionFrame(t, t, 0, (wire.Detection("blue", 0, 0.0, 0.0, 0.0),)))


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_every_robot_before_exit(sig: signal.Signals) -> None:
    robots = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    robots.bind(("127.0.0.1", 0))
    robots.settimeout(0.01)
    command = [
        sys.executable,
        "-m",
        "hier_ssl.cli",
        "deploy",
        "direct",
        "--vision",
        "127.0.0.1:0",
        "--commands",
        f"grsim:127.0.0.1:{robots.getsockname()[1]}",
        "--team",
        "blue",
        "--robots",
        "0,1",
        "--targets",
        "0:1.5,0.5,0;1:-1,-1,0",
        "--task",
        "proposed",
    ]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=ROOT, env=ENV)
    vision = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vision.bind(("127.0.0.1", 0))
    try:
        to = ("127.0.0.1", json.loads(process.stdout.readline())["vision_port"])
        received, signalled = [], None
        start = time.monotonic()
        while time.monotonic() - start < 10 and process.poll() is None:
            vision.sendto(_frame(time.time()), to)  # robot 0 in sight throughout; vision stamps UNIX time
            try:
                received.append((time.monotonic(), wire.parse_grsim(robots.recv(4096))[1]))
            except TimeoutError:
                pass
            moving = any(c[0][1:] != (0.0, 0.0, 0.0) for _, c in received)
            if signalled is None and moving and time.monotonic() - start > 0.3:
                process.send_signal(sig)
                signalled = time.monotonic()
        assert process.wait(timeout=5) == 0
        while True:  # the stops sent on the way out
            try:
                received.append((time.monotonic(), wire.parse_grsim(robots.recv(4096))[1]))
            except TimeoutError:
                break
    finally:
        if process.poll() is None:
            process.kill()
        vision.close()
        robots.close()
    assert signalled is not None, "robot 0 never drove"
    last = received[-1][1]
    assert sorted(last) == [(0, 0.0, 0.0, 0.0), (1, 0.0, 0.0, 0.0)]
    summary = json.loads(process.stdout.readline())
    assert summary["frames"] > 10 and summary["dropped"] == {}


def test_the_field_command_publishes_vision_and_stops_on_sigterm() -> None:
    vision = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vision.bind(("127.0.0.1", 0))
    vision.settimeout(2.0)
    command = [
        sys.executable,
        "-m",
        "hier_ssl.cli",
        "field",
        "proposed",
        "--vision-port",
        str(vision.getsockname()[1]),
        "--grsim-port",
        "0",
        "--simulation-port",
        "0",
        "--episodes",
        "1",
        "--noise-mm",
        "0",
        "--rate",
        "100",
    ]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=ROOT, env=ENV)
    try:
        ports = json.loads(process.stdout.readline())
        assert ports["grsim_port"] > 0 and ports["task"] == "proposed"
        frames = [wire.parse_vision(vision.recv(65536)) for _ in range(20)]
        assert {type(f) for f in frames} >= {wire.DetectionFrame}
    finally:
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=5) == 0
        vision.close()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--vision", "localhost:10006"], "expected IP:PORT"),
        (["--vision", "127.0.0.1:10006", "--commands", "udp"], "expected grsim|simulation"),
        (["--robots", "0,0"], "robots '0,0': an id is named twice"),
        (["--robots", "0-3,2"], "an id is named twice"),
        (["--robots", "0-16"], "robots '0-16': '0-16' is not in 0..15 (low to high)"),
        (["--robots", "1,5-2"], "'5-2' is not in 0..15"),
        (["--robots", "1,x-2"], "robots '1,x-2': 'x-2' is not an id or a range like 0-10"),
        (["--robots", "-1"], "'-1' is not an id or a range"),
        (["--targets", "0:1,2,x"], "expected ID:x,y,theta"),
        (["--targets", "5:1,2,3"], "robot 5 is not a controlled robot"),
        (["--vision", "224.5.23.2:10006"], "multicast group: name --vision-interface"),
    ],
)
def test_bad_deploy_options_end_with_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    base = {"--vision": "127.0.0.1:0", "--commands": "grsim:127.0.0.1:9", "--team": "blue", "--robots": "0"}
    for flag, value in zip(argv[::2], argv[1::2], strict=True):
        base[flag] = value
    args = ["deploy", "direct", "--task", "proposed"] + [x for kv in base.items() for x in kv]
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_option_parsers() -> None:
    assert parse_robots("0,3,5") == [0, 3, 5]
    assert parse_robots("0-10") == list(range(11))
    assert parse_robots("12-15,0-1,7") == [12, 13, 14, 15, 0, 1, 7]
    assert parse_robots("4-4") == [4]
    assert parse_targets("0:1,2,0.5;1:-1,0,0,0.2,0") == {0: [1.0, 2.0, 0.5], 1: [-1.0, 0.0, 0.0, 0.2, 0.0]}
    assert command_target("simulation", "yellow") == ("simulation", ("127.0.0.1", 10302))
    assert command_target("grsim:127.0.0.1:20011", "blue") == ("grsim", ("127.0.0.1", 20011))
    assert parse_address("127.0.0.1:0", any_port=True) == ("127.0.0.1", 0)
    with pytest.raises(ValueError, match="not in 1..65535"):
        parse_address("127.0.0.1:0")
    with pytest.raises(ValueError, match="--vision-interface"):
        open_vision("224.5.23.2", 10006)


def test_targets_from_a_yaml_file(tmp_path: Path) -> None:
    path = tmp_path / "targets.yaml"
    path.write_text("0: [1.0, 0.5, 0.0]\n2: [-1.0, 0.0, 1.57]\n")
    assert parse_targets(str(path)) == {0: [1.0, 0.5, 0.0], 2: [-1.0, 0.0, 1.57]}
    path.write_text("- 1\n")
    with pytest.raises(ValueError, match="expected a mapping"):
        parse_targets(str(path))


def test_the_deploy_commands_give_torch_one_openmp_thread_before_it_loads() -> None:
    # Set after torch has loaded, one thread still leaves OpenMP's pool of one thread per core, which a
    # call after the loop's sleep waited on; the variable has to be there when torch loads.
    env = {k: v for k, v in ENV.items() if k != "OMP_NUM_THREADS"}
    script = (
        "from hier_ssl.cli.deploy import _one_thread; _one_thread(); import torch; "
        "print(torch.get_num_threads(), 'omp_get_max_threads() : 1' in torch.__config__.parallel_info())"
    )
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "True"]


def test_lockstep_is_an_option_of_both_commands_and_off_by_default() -> None:
    parser = cli.build_parser()
    deploy = ["deploy", "sampling", "--vision", "127.0.0.1:10006", "--commands", "grsim", "--team", "blue"]
    deploy += ["--robots", "0"]
    assert not parser.parse_args(deploy).lockstep and parser.parse_args([*deploy, "--lockstep"]).lockstep
    assert not parser.parse_args(["field"]).lockstep and parser.parse_args(["field", "--lockstep"]).lockstep
