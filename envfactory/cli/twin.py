"""The digital twin's command: a rosbridge stand-in on a robot's real topics, with its faults."""

from __future__ import annotations

from typing import List, Optional

import typer
from typer.core import TyperCommand

from envfactory.cli.common import command, console, fail
from envfactory.cli.lookup import robots_with_backend, unknown_robot
from envfactory.twin import Twin

TWIN_ROBOT_HELP = "Robot name (the Robot column of `envfactory list`)"


class _TwinHelp(TyperCommand):
    """`twin --help` names the robots with a real path (a rosbridge ID), read from the registered specs when
    the help is shown: a robot YAML added later is listed without touching this file, and no other command
    pays for composing the families."""

    def format_help(self, ctx, formatter) -> None:
        robots = robots_with_backend("rosbridge")
        for param in self.params:
            if param.name == "robot":
                param.help = f"{TWIN_ROBOT_HELP}; robots with a real path: {', '.join(robots) or 'none'}"
        super().format_help(ctx, formatter)


@command(cls=_TwinHelp)
def twin(
    robot: str = typer.Argument(..., help=TWIN_ROBOT_HELP),
    task: str = typer.Option("push", help="The task whose objects it simulates (push has the cube)"),
    port: int = typer.Option(9090, help="Port of the rosbridge websocket; 0 picks a free one"),
    host: str = typer.Option("127.0.0.1", help="Interface to listen on (loopback by default)"),
    group_move: Optional[float] = typer.Option(
        None,
        help="Seconds every command without a duration takes (the "
        "driver's stock time profile, until the env sets its "
        "own); default: the driver's (xs_sdk: 2.0), else the "
        "robot YAML's ros.arm_command.profile_time_s",
    ),
    speed_scaling: float = typer.Option(
        1.0, min=0.0, max=1.0, help="The UR trajectory controller's speed scaling (the pendant's slider: 1.0 is 100%)"
    ),
    delay: float = typer.Option(0.0, help="Fault: latency added to every published message, s"),
    stop_joint_states_after: Optional[float] = typer.Option(None, help="Fault: stop publishing joint states after S s"),
    stop_object_poses_after: Optional[float] = typer.Option(
        None, help="Fault: stop publishing the cube pose after S s"
    ),
    freeze_after: Optional[float] = typer.Option(None, help="Fault: the driver freezes after S s (no joint states)"),
    freeze_for: float = typer.Option(2.0, help="... for this many seconds"),
    malformed_after: Optional[float] = typer.Option(None, help="Fault: publish malformed joint states after S s"),
    malformed_count: int = typer.Option(1, help="... this many (a NaN position, sent as null)"),
    kill_after: Optional[float] = typer.Option(None, help="Fault: the rosbridge server dies after S s"),
    down_for: float = typer.Option(4.0, help="... and comes back after this many seconds"),
    drop_after: Optional[float] = typer.Option(None, help="Fault: drop every connection after S s"),
    ignore_commands_after: Optional[float] = typer.Option(
        None, help="Fault: after S s the driver takes commands but executes none (a stopped controller)"
    ),
    topic_type: List[str] = typer.Option(
        None, help="Fault: the driver registers TOPIC with another TYPE (TOPIC=TYPE), repeatable"
    ),
    no_rosapi: bool = typer.Option(False, help="Fault: serve without rosapi (its services do not exist)"),
):
    """A rosbridge stand-in serving a PyBullet robot and cube on the real topics: rehearse Real IDs on it."""
    import time

    real_robots = robots_with_backend("rosbridge")
    if robot not in real_robots:
        fail(unknown_robot(robot, real_robots, "robots with a real path"))
    types = {}
    for item in topic_type or []:
        topic, sep, type_name = item.partition("=")
        if not sep:
            fail(f"--topic-type {item!r}: write TOPIC=TYPE")
        types[topic] = type_name
    try:
        stand_in = Twin(
            robot, task, host=host, port=port, topic_types=types, group_move_s=group_move, speed_scaling=speed_scaling
        ).start()
    except (ValueError, OSError) as exc:
        fail(str(exc))
    ros, faults = stand_in.ros, stand_in.faults
    faults.delay_s, faults.no_rosapi = delay, no_rosapi
    console.print(
        f"twin of {robot} ({task}) at ws://{host}:{stand_in.port}, playing "
        f"{ros.driver or 'the topic map as declared'}; "
        f"publishing {ros.joint_states.topic} and {[t.topic for t in ros.object_poses.values()]}, "
        f"executing {ros.arm_command.topic}"
        f"{' and ' + ros.gripper_command.topic if ros.gripper_command else ''}. Ctrl-C stops it."
    )
    poses = [t.topic for t in ros.object_poses.values()]
    schedule = [
        (stop_joint_states_after, lambda: faults.silence(ros.joint_states.topic)),
        (stop_object_poses_after, lambda: [faults.silence(topic) for topic in poses]),
        (freeze_after, lambda: faults.silence(ros.joint_states.topic, freeze_for)),
        (malformed_after, lambda: faults.corrupt(ros.joint_states.topic, malformed_count)),
        (kill_after, lambda: stand_in.kill(down_for)),
        (drop_after, stand_in.drop_connections),
        (ignore_commands_after, lambda: setattr(faults, "ignore_commands", True)),
    ]
    start = time.monotonic()
    pending = sorted(((after, act) for after, act in schedule if after is not None), key=lambda item: item[0])
    try:
        while True:
            while pending and time.monotonic() - start >= pending[0][0]:
                pending.pop(0)[1]()
            time.sleep(0.05)
    except KeyboardInterrupt:
        console.print(
            f"twin stopped; its driver received {len(stand_in.received)} commands; "
            f"the server refused {len(stand_in.server.errors)} messages"
        )
    finally:
        stand_in.stop()
