"""The robot side: ``robot keys`` (CURVE key pairs), ``robot serve`` (this robot's sensors and motion) and
``robot serve-sim`` (the embedded world served as a robot); docs/robot.md."""

from __future__ import annotations

import argparse

from drivenav.cli.common import Commands, add_config_options, settings
from drivenav.eval.options import path, seed
from drivenav.robot.registry import add_part_options


def add_robot(commands: Commands) -> None:
    parser = commands.add_parser("robot", help="the robot side: keys, serve a robot, serve the embedded world")
    sub = parser.add_subparsers(dest="robot_command", required=True)
    keys = sub.add_parser("keys", help="write CURVE key pairs and the allow-list (DIR/server.key, DIR/client.key, ...)")
    keys.add_argument("dir", type=path)
    keys.set_defaults(handler=_cmd_robot_keys)
    serve = sub.add_parser("serve", help="serve this robot's sensors and motion (ROS 2 topics or a ROS 2 bag)")
    serve.add_argument("--bind", default="tcp://127.0.0.1:5555", help="endpoint (default tcp://127.0.0.1:5555)")
    serve.add_argument("--keys", type=path, default=None, help="CURVE keys (required off loopback)")
    serve.add_argument("--lidar", action="store_true", help="send LiDAR occupancy in the camera's field of view")
    serve.add_argument("--jpeg", action="store_true", help="RGB as JPEG (default raw)")
    add_config_options(serve)
    serve.set_defaults(handler=_cmd_robot_serve)
    add_part_options(serve)  # last: a plug-in part's options are checked against every other option
    sim = sub.add_parser("serve-sim", help="the embedded world served as a robot, with metrics per episode")
    sim.add_argument("--scenes", default="procedural", help="a --scenes SPEC")
    sim.add_argument("--episodes", required=True, type=path, help="the episodes file the brain will run")
    sim.add_argument("--bind", default="tcp://127.0.0.1:5555", help="endpoint (default tcp://127.0.0.1:5555)")
    sim.add_argument("--keys", type=path, default=None, help="CURVE keys (required off loopback)")
    sim.add_argument("--seed", type=int, default=0, help="the scenes' seed (procedural scenes)")
    sim.add_argument("--lidar", action="store_true", help="simulate a 2-D LiDAR and send its occupancy")
    add_config_options(sim)
    sim.set_defaults(handler=_cmd_robot_serve_sim)


def _cmd_robot_keys(args: argparse.Namespace) -> int:
    from drivenav.wire.security import write_keys

    for written in write_keys(args.dir):
        print(written)
    return 0


def _cmd_robot_serve(args: argparse.Namespace) -> int:
    from drivenav.robot.registry import robot_parts
    from drivenav.robot.serve import serve_robot
    from drivenav.wire.security import check_bind

    check_bind(args.bind, args.keys)  # before any topic or file is opened
    sim = settings(args, None).sim
    source, motion = robot_parts(args, sim)
    serve_robot(args.bind, args.keys, source, motion, sim, args.lidar, args.jpeg)
    return 0


def _cmd_robot_serve_sim(args: argparse.Namespace) -> int:
    from drivenav.robot.serve import serve_simulation

    sim = settings(args, None).sim
    serve_simulation(args.scenes, seed(args.seed), args.episodes, args.bind, args.keys, args.lidar, sim)
    return 0


SERVING = (_cmd_robot_serve, _cmd_robot_serve_sim)
"""The handlers that serve until stopped: Ctrl-C halts the robot rather than interrupting a run."""
