"""What the tests of Real IDs against the twin share: fast timing, and reading what the
twin's arm received."""

import time

# wall-clock steps of 0.1 s, each command's trajectory done in 0.05 s
FAST = {"action_cycle_time": 0.1, "environment_loop_rate": 10.0, "action_speed": 0.05}
UR5E_ARM = "/scaled_pos_joint_traj_controller/command"
UR5E_JOINTS = "/ur5e/joint_states"
VX300S_ARM = "/vx300s/commands/joint_group"
VX300S_JOINTS = "/vx300s/joint_states"
NED2_ARM = "/niryo_robot_follow_joint_trajectory_controller/command"
NED2_JOINTS = "/joint_states"


def make_real(make, env_id, stand_in, **kwargs):
    return make(env_id, rosbridge_port=stand_in.port, **{"allow_real_robot_motion": True, **FAST, **kwargs})


def on(stand_in, topic):
    return [r.msg for r in stand_in.received if r.topic == topic]


def is_stop(msg):
    return msg.get("points") == []


def settled(stand_in, quiet=0.3):
    """How many messages the twin has once nothing new arrived for `quiet` seconds."""
    count = len(stand_in.received)
    while True:
        time.sleep(quiet)
        if len(stand_in.received) == count:
            return count
        count = len(stand_in.received)


def wait_for(predicate, timeout=3.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True
