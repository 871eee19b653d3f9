"""``hier-ssl deploy`` (a manager on an SSL stack), ``hier-ssl field`` (the loopback field server) and the
options of ``hier-ssl bench deploy``. The ``deploy`` extra (protobuf) is imported inside the commands."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading

from hier_ssl.cli.common import WORKER_HELP, positive_int, worker_spec


def _one_thread() -> None:
    """One OpenMP thread for torch's operators (an exported .pt file or a run directory's network), set
    before torch loads: it is called on a few rows, and waking a pool costs milliseconds on a busy machine.
    ``torch.set_num_threads(1)`` after torch has loaded is not enough: the pool OpenMP built at load stays,
    and after the loop's 25 ms sleeps one call in ten spun and then yielded inside the network for 8-14 ms
    (the network for 6 robots under SCHED_FIFO at load 5: p50 / p90 0.92 / 8.8 ms a call, 0.80 / 0.93 ms
    with the variable set first)."""
    os.environ["OMP_NUM_THREADS"] = "1"
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def _stop_on_signals() -> threading.Event:
    """An event that SIGINT and SIGTERM set: the loops stop and send their robots a stop."""
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    return stop


def _priority_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--priority",
        type=int,
        choices=range(100),
        default=10,
        metavar="0-99",
        help="the loop thread's SCHED_FIFO priority where permitted (0: time-shared; default 10)",
    )


def add_deploy(subparsers: argparse._SubParsersAction) -> None:
    deploy = subparsers.add_parser(
        "deploy", help="drive SSL robots: SSL-Vision packets in, grSim / simulation-protocol commands out"
    )
    deploy.add_argument(
        "manager",
        help="a run directory, an exported .pt / .onnx file, or a planner: direct, sampling, trajectory, "
        "with settings where given (sampling+trapped=brake)",
    )
    deploy.add_argument(
        "--vision", required=True, help="HOST:PORT to receive SSL-Vision on (127.0.0.1:10006)"
    )
    deploy.add_argument(
        "--vision-source", default="127.0.0.1", help="the only sender IP whose vision packets are accepted"
    )
    deploy.add_argument(
        "--vision-interface", default=None, help="with a multicast --vision: this machine's interface IP"
    )
    deploy.add_argument(
        "--commands", required=True, help="grsim|simulation[:HOST:PORT] (default ports 20011; 10301 / 10302)"
    )
    deploy.add_argument("--team", choices=("blue", "yellow"), required=True)
    deploy.add_argument("--robots", required=True, help="controlled robot ids, e.g. 0,1 or 0-10 or 0-3,7")
    deploy.add_argument(
        "--targets", default=None, help="ID:x,y,theta[;ID:...] or a YAML file {id: [x, y, theta]}"
    )
    deploy.add_argument(
        "--control",
        type=int,
        default=None,
        metavar="PORT",
        help="TCP port on 127.0.0.1 for JSON-line targets",
    )
    deploy.add_argument("--task", default=None, help="a planner's task or scenario (default obstacle)")
    deploy.add_argument("--worker", type=worker_spec, default=None, help=WORKER_HELP)
    deploy.add_argument("--frame-skip", type=positive_int, default=None, help="control periods per decision")
    deploy.add_argument(
        "--worker-feedback",
        choices=("model", "command", "tracked"),
        default="model",
        help="the velocity the worker steers from: the commands' answer within the acceleration limits (as "
        "in training), the last command, or the tracked velocity",
    )
    _priority_option(deploy)
    deploy.add_argument(
        "--lockstep",
        action="store_true",
        help="tick on each world step's frames, for a field server in lockstep (hier-ssl field --lockstep)",
    )
    deploy.add_argument(
        "--referee",
        default=None,
        metavar="HOST:PORT",
        help="receive the game controller's Referee messages there (a multicast group joins on "
        "--vision-interface) and play by its rules: HALT stops, STOP and free kicks keep the zones and speed",
    )
    deploy.add_argument(
        "--referee-source",
        default=None,
        help="the only sender IP whose referee packets are accepted (default: --vision-source)",
    )
    deploy.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    deploy.set_defaults(func=_deploy)


def _deploy(args: argparse.Namespace) -> int:
    import numpy as np

    from hier_ssl.deploy.assemble import DeploySettings, build_loop, parse_robots, parse_targets

    settings = DeploySettings(
        args.manager,
        args.vision,
        args.commands,
        args.team,
        parse_robots(args.robots),
        parse_targets(args.targets),
        args.vision_source,
        args.control,
        args.vision_interface,
        args.task,
        args.worker,
        args.frame_skip,
        args.worker_feedback,
        args.priority,
        args.lockstep,
        args.referee,
        args.referee_source,
    )
    _one_thread()
    loop = build_loop(settings)
    loop.report = lambda line: print(line, file=sys.stderr, flush=True)
    ports = {"vision_port": loop.vision.getsockname()[1], "commands": list(loop.sender.address)}
    ports["control_port"] = loop.control.port if loop.control is not None else None
    ports["referee_port"] = loop.referee.sock.getsockname()[1] if loop.referee is not None else None
    print(json.dumps(ports), flush=True)
    try:
        stats = loop.run(_stop_on_signals(), args.duration)
    finally:
        loop.close()
    latency = np.percentile(stats.latencies, [50, 99]) * 1e3 if stats.latencies else [None, None]
    summary = {
        "frames": stats.frames,
        "dropped": dict(stats.dropped),
        "ticks": stats.ticks,
        "p50_ms": latency[0],
        "p99_ms": latency[1],
        "simulator_errors": stats.simulator_errors.total(),
        "scheduling": stats.scheduling,
    }
    print(json.dumps(summary), flush=True)
    return 0


def add_field(subparsers: argparse._SubParsersAction) -> None:
    field = subparsers.add_parser(
        "field", help="a loopback field server: hier_ssl's world as SSL-Vision packets, taking robot commands"
    )
    field.add_argument(
        "task", nargs="?", default="obstacle", help="a paper task or scenario (default obstacle)"
    )
    field.add_argument("--vision-port", type=int, default=10006, help="send SSL-Vision to 127.0.0.1:PORT")
    field.add_argument("--grsim-port", type=int, default=20011, help="take grSim commands on 127.0.0.1:PORT")
    field.add_argument(
        "--simulation-port", type=int, default=10301, help="take RobotControl on 127.0.0.1:PORT"
    )
    field.add_argument(
        "--team", choices=("blue", "yellow"), default="blue", help="the controlled robots' team"
    )
    field.add_argument(
        "--control", type=int, default=None, metavar="PORT", help="send targets to 127.0.0.1:PORT"
    )
    field.add_argument("--cameras", type=positive_int, default=2)
    field.add_argument("--rate", type=float, default=60.0, help="frames per second of each camera")
    field.add_argument("--noise-mm", type=float, default=2.0, help="position noise, one standard deviation")
    field.add_argument("--noise-deg", type=float, default=0.5, help="heading noise, one standard deviation")
    field.add_argument("--latency-ms", type=float, default=0.0, help="from capture to send")
    field.add_argument("--drop", type=float, default=0.0, help="probability of missing a detection")
    field.add_argument(
        "--episodes", type=positive_int, default=None, help="stop after so many (default never)"
    )
    field.add_argument("--seed", type=int, default=0)
    field.add_argument(
        "--lockstep",
        action="store_true",
        help="step the world once per command period, waiting for the commands (at most 100 ms), instead "
        "of every 25 ms of wall-clock time; the controller runs with deploy --lockstep",
    )
    field.add_argument(
        "--referee-script",
        default=None,
        metavar="SCRIPT",
        help="play referee: TIME:COMMAND entries of each episode's time, comma-separated, a ball placement "
        "with its position (m), e.g. 2.0:STOP,5.0:FORCE_START,8.0:BALL_PLACEMENT_YELLOW@1.0,-0.5; the "
        "game runs before the first; fouls are counted per robot and kind",
    )
    field.add_argument(
        "--referee-port",
        type=int,
        default=10003,
        help="send the Referee messages to 127.0.0.1:PORT (deploy --referee 127.0.0.1:PORT)",
    )
    field.add_argument(
        "--ball",
        default=None,
        metavar="X,Y",
        help="a ball lying still there, m (default: none; with a referee script, the centre spot)",
    )
    field.set_defaults(func=_field)


def _field(args: argparse.Namespace) -> int:
    import math

    from hier_ssl.deploy.cameras import Cameras
    from hier_ssl.deploy.field import FieldServer
    from hier_ssl.deploy.referee_script import parse_script, parse_xy
    from hier_ssl.envs import task_config
    from hier_ssl.world.field import get_field

    config = task_config(args.task)
    referee = None
    if args.referee_script is not None:
        referee = parse_script(args.referee_script, get_field(config.field))
    cameras = Cameras(
        args.cameras,
        rate=args.rate,
        pos_noise=args.noise_mm / 1000,
        angle_noise=math.radians(args.noise_deg),
        drop=args.drop,
        latency=args.latency_ms / 1000,
    )
    server = FieldServer(
        config,
        args.vision_port,
        args.team,
        cameras,
        args.grsim_port,
        args.simulation_port,
        args.control,
        args.seed,
        lockstep=args.lockstep,
        referee=referee,
        referee_port=args.referee_port,
        ball=None if args.ball is None else parse_xy(args.ball, "ball"),
    )
    ports = {"vision_port": args.vision_port, "grsim_port": server.grsim_port}
    refereed = referee is not None or server.referee.game  # a game scenario plays its own referee
    ports["referee_port"] = args.referee_port if refereed else None
    print(json.dumps({"task": args.task, **ports, "simulation_port": server.simulation_port}), flush=True)
    try:
        server.run(args.episodes, _stop_on_signals(), lambda record: print(json.dumps(record), flush=True))
    finally:
        server.close()
    if refereed:
        print(json.dumps({"fouls": server.referee.foul_counts()}), flush=True)
    return 0


def add_bench_deploy(bench: argparse.ArgumentParser) -> None:
    """``hier-ssl bench deploy``'s options."""
    bench.add_argument("--json", action="store_true", help="one JSON object per line")
    bench.add_argument("--run", default=None, help="a manager run directory: a task row of its own task")
    bench.add_argument("--seconds", type=float, default=5.0, help="seconds of each latency row")
    bench.add_argument("--episodes", type=positive_int, default=10, help="episodes of each task row")
    _priority_option(bench)
    bench.add_argument("--noise-mm", type=float, default=2.0, help="the task rows' vision position noise")
    bench.add_argument("--noise-deg", type=float, default=0.5, help="the task rows' vision heading noise")
    bench.add_argument(
        "--rows",
        default="tracking,latency,task",
        help="which rows, comma-separated: tracking, latency, task, game (game_stop under the field server's "
        "referee; default tracking,latency,task)",
    )
    bench.add_argument(
        "--robots",
        default="1,6",
        help="the latency rows' robot counts, comma-separated: 1 (obstacle), 6 (formation), 11 (formation on "
        "the Division A field) (default 1,6)",
    )
    bench.set_defaults(func=_bench_deploy)


def _bench_deploy(args: argparse.Namespace) -> int:
    from hier_ssl.deploy.bench import LATENCY_TASKS, ROWS, deploy_rows

    rows = tuple(args.rows.split(","))
    if not set(rows) <= set(ROWS):
        raise ValueError(f"rows {args.rows!r}: expected a comma-separated choice of {', '.join(ROWS)}")
    counts = tuple(args.robots.split(","))
    if not set(counts) <= {str(k) for k in LATENCY_TASKS}:
        raise ValueError(
            f"robots {args.robots!r}: expected a comma-separated choice of {sorted(LATENCY_TASKS)}"
        )
    _one_thread()
    noise = (args.noise_mm, args.noise_deg)
    robots = tuple(map(int, counts))
    for row in deploy_rows(args.run, args.seconds, args.episodes, args.priority, noise, rows, robots):
        print(
            json.dumps(row) if args.json else "  " + ", ".join(f"{k} {v}" for k, v in row.items()), flush=True
        )
    return 0
