"""The ROS message codecs and frame lookups the rosbridge backend and the twin share."""

import numpy as np
import pinocchio as pin
import pytest

from envfactory.backends.base import CommandIgnored
from envfactory.backends.rosbridge import messages
from envfactory.backends.rosbridge.feeds import beyond
from envfactory.backends.rosbridge.follow import FollowWatch
from envfactory.backends.rosbridge.link import same_type
from envfactory.backends.rosbridge.messages import MalformedMessage
from envfactory.backends.rosbridge.transforms import FrameGraph
from envfactory.schema.models import ArmCommand, GripperCommand, StaticTransform

NAMES = ["elbow", "shoulder", "waist"]


def test_joint_state_is_matched_by_name_not_order():
    msg = messages.encode_joint_state(["waist", "elbow", "shoulder", "extra"], [3, 1, 2, 9], [0.3, 0.1, 0.2, 0], 5.0)
    position, velocity = messages.decode_joint_state(msg, NAMES)
    np.testing.assert_array_equal(position, [1, 2, 3])
    np.testing.assert_array_equal(velocity, [0.1, 0.2, 0.3])


@pytest.mark.parametrize(
    "msg, reason",
    [
        ({"position": [1, 2, 3]}, "without a 'name' list"),
        ({"name": NAMES, "position": [1, 2]}, "has 2 values, expected 3"),
        ({"name": NAMES, "position": [1, float("nan"), 3]}, "non-finite"),
        ({"name": NAMES, "position": ["a", 2, 3]}, "not a list of numbers"),
        ({"name": ["elbow", "shoulder", "wrist"], "position": [1, 2, 3]}, "lacks joints ['waist']"),
    ],
)
def test_malformed_joint_states_are_rejected_with_the_reason(msg, reason):
    with pytest.raises(MalformedMessage, match=reason.replace("[", r"\[").replace("]", r"\]")):
        messages.decode_joint_state(msg, NAMES)


def test_pose_round_trip_and_bad_quaternion():
    msg = messages.encode_pose("world", [1, 2, 3], [0, 0, 0, 1], 1.5)
    frame, position, quaternion = messages.decode_pose(msg)
    assert frame == "world" and list(position) == [1, 2, 3] and list(quaternion) == [0, 0, 0, 1]
    with pytest.raises(MalformedMessage, match="unit quaternion"):
        messages.decode_pose(messages.encode_pose("world", [1, 2, 3], [0, 0, 0, 3], 0))
    with pytest.raises(MalformedMessage, match="lacks"):
        messages.decode_pose({"header": {}})


@pytest.mark.parametrize("encoding", ["joint_trajectory", "joint_group"])
def test_arm_command_round_trip_and_stop(encoding):
    command = ArmCommand(topic="/arm", type="t", encoding=encoding)
    msg = messages.encode_arm(command, NAMES, [0.1, 0.2, 0.3], 0.25)
    target, duration = messages.decode_arm(command, NAMES, msg, default_duration=0.4)
    np.testing.assert_allclose(target, [0.1, 0.2, 0.3])
    assert duration == pytest.approx(0.25 if encoding == "joint_trajectory" else 0.4)
    stop = messages.encode_arm_stop(command, NAMES, np.array([1.0, 2.0, 3.0]))
    target, _ = messages.decode_arm(command, NAMES, stop, 0.4)
    if encoding == "joint_trajectory":
        assert target is None  # the empty trajectory: the controller holds
    else:
        np.testing.assert_allclose(target, [1, 2, 3])  # hold the last known position
        assert messages.encode_arm_stop(command, NAMES, None) is None  # nothing to hold: nothing sent


@pytest.mark.parametrize(
    "encoding, expected",
    [
        ("float64_array", {"layout": {"dim": [], "data_offset": 0}, "data": [0.7]}),
        ("joint_single", {"name": "gripper", "cmd": 0.7}),
    ],
)
def test_gripper_command_encodings(encoding, expected):
    command = GripperCommand(topic="/g", type="t", encoding=encoding)
    assert messages.encode_gripper(command, 0.7, 0.0, 0.8) == expected
    assert messages.decode_gripper(command, expected, 0.0, 0.8) == 0.7


def test_camera_pose_reaches_the_task_frame_through_static_and_tf_transforms():
    graph = FrameGraph("world", {"base_link": StaticTransform(parent="world", xyz=(0, 0, 0.59))})
    # a camera above the table looking straight down, announced on /tf
    down = pin.rpy.rpyToMatrix(np.pi, 0, 0)
    x, y, z, w = pin.Quaternion(down).coeffs()
    graph.learn(
        {
            "transforms": [
                {
                    "header": {"frame_id": "base_link"},
                    "child_frame_id": "camera",
                    "transform": {
                        "translation": {"x": 0.5, "y": 0.0, "z": 0.8},
                        "rotation": {"x": x, "y": y, "z": z, "w": w},
                    },
                }
            ]
        }
    )
    position, quaternion = graph.to_task("camera", np.array([0.0, 0.1, 0.6]), np.array([0, 0, 0, 1.0]))
    np.testing.assert_allclose(position, [0.5, -0.1, 0.59 + 0.8 - 0.6], atol=1e-9)
    assert np.allclose(np.abs(quaternion), np.abs([x, y, z, w]))
    with pytest.raises(KeyError, match="no transform from frame 'kinect2_link'"):
        graph.to_task("kinect2_link", np.zeros(3), np.array([0, 0, 0, 1.0]))


def test_null_in_a_joint_state_is_named():
    with pytest.raises(MalformedMessage, match="holds null"):
        messages.decode_joint_state({"name": NAMES, "position": [1.0, None, 3.0]}, NAMES)


@pytest.mark.parametrize(
    "age, limit, text",
    [
        (0.5004, 0.5, "0.51 s old (limit 0.50 s)"),
        (0.50001, 0.5, "0.51 s old (limit 0.50 s)"),
        (2.0, 0.5, "2.00 s old (limit 0.50 s)"),
        (0.5, 0.4999, "0.5000 s old (limit 0.4999 s)"),
    ],
)
def test_an_age_past_its_limit_reads_as_past_it(age, limit, text):
    assert beyond(age, limit) == text


def test_the_follow_watch_waits_for_motion_and_keeps_its_clock_across_commands():
    watch = FollowWatch("/arm", timeout=1.0)
    here = np.zeros(3)
    watch.commanded(here, here + 0.001, now=0.0)  # a hold asks for no motion
    watch.check(now=10.0)
    watch.commanded(here, here + 0.2, now=10.0)
    watch.commanded(here, here + 0.3, now=10.6)  # a later command does not restart the clock
    watch.observe(here + 0.001, now=10.8)  # noise is not motion
    with pytest.raises(CommandIgnored, match="did not follow the command on /arm"):
        watch.check(now=11.1)
    watch.clear()
    watch.commanded(here, here + 0.2, now=20.0)
    watch.observe(here + np.array([0.0, 0.01, 0.0]), now=20.25)  # it moved: the command's latency is 0.25 s
    watch.check(now=25.0)
    assert watch.take_latencies() == [pytest.approx(0.25)] and watch.take_latencies() == []


def test_ros2_type_names_match_their_ros1_spelling():
    assert same_type("trajectory_msgs/msg/JointTrajectory", "trajectory_msgs/JointTrajectory")
    assert not same_type("std_msgs/msg/Float64MultiArray", "trajectory_msgs/JointTrajectory")


def test_a_real_motion_is_done_at_its_target_and_at_rest_and_overdue_past_its_margin():
    """A step ends as a simulated one does: the arm at its target and still; one that moves on past its target, or
    never gets there, is overdue once the driver's time and the margin are over."""
    from envfactory.backends.rosbridge.motion import MotionUnfinished, MotionWatch
    from envfactory.schema.driver import Settle

    watch = MotionWatch("/arm", Settle(tolerance=0.01, velocity=0.05, margin_s=0.5))
    target = np.array([0.3, -0.2])
    watch.commanded(np.zeros(2), target, now=10.0, length_s=0.2)
    assert not watch.done(np.array([0.1, -0.2]), np.zeros(2), now=10.1)  # on its way
    assert not watch.done(target + 0.005, np.array([0.0, 0.4]), now=10.2)  # at the target, still moving
    watch.check(target + 0.005, np.array([0.0, 0.4]), now=10.6)  # within 0.2 + 0.5 s: no fault yet
    with pytest.raises(MotionUnfinished, match=r"within 0.70 s .* fastest joint at 0.400 rad/s \(settled below 0.05\)"):
        watch.check(target + 0.005, np.array([0.0, 0.4]), now=10.8)
    assert watch.done(target + 0.005, np.array([0.0, 0.01]), now=10.9)
    assert watch.motion_time() == pytest.approx(0.9) and watch.gap == pytest.approx(0.005)


def test_an_arm_held_back_at_rest_has_done_its_motion_once_the_driver_is_through():
    """An arm pushing something stops a little short, in simulation as on the real arm: at rest within held_back of
    its target once its driver's time is over, its motion is done (the gap recorded); farther, it is overdue."""
    from envfactory.backends.rosbridge.motion import MotionUnfinished, MotionWatch
    from envfactory.schema.driver import Settle

    watch = MotionWatch("/arm", Settle(tolerance=0.005, velocity=0.05, held_back=0.05, margin_s=1.0))
    target = np.array([0.3, -0.2])
    watch.commanded(np.zeros(2), target, now=0.0, length_s=0.2)
    still = np.zeros(2)
    assert not watch.done(target - 0.03, still, now=0.1)  # at rest before the driver's time: not yet started
    assert watch.done(target - 0.03, still, now=0.25) and watch.gap == pytest.approx(0.03)
    watch.commanded(target - 0.03, target, now=1.0, length_s=0.2)
    assert not watch.done(target - 0.03, still, now=1.5)  # never moved: no driver carried it out
    watch.commanded(np.zeros(2), target, now=1.0, length_s=0.2)
    assert not watch.done(target - 0.08, still, now=1.5)  # held back farther than 0.05 rad
    with pytest.raises(MotionUnfinished, match="still 0.080 rad from its target"):
        watch.check(target - 0.08, still, now=2.3)


def test_an_arm_pressing_into_what_holds_it_has_done_its_motion_at_the_end_of_the_margin():
    """Pressing into a block it pushes, an arm can creep on for seconds without arriving: at the end of the
    margin, held back and slowed to a creep (or a tremble at its target) from its fastest, its motion is done.
    One still running at over a quarter of its fastest, held back too far, or running slowly all along (a driver
    at a low speed scaling, not a block) is overdue."""
    from envfactory.backends.rosbridge.motion import MotionUnfinished, MotionWatch
    from envfactory.schema.driver import Settle

    watch = MotionWatch("/arm", Settle(tolerance=0.005, velocity=0.01, held_back=0.05, margin_s=1.0))
    target = np.array([0.3, -0.2])
    running = np.array([0.0, 0.25])  # rad/s: the arm on its way
    creeping = np.array([0.0, 0.02])  # rad/s: under a quarter of its fastest

    def pressed(gap_rad: float, speed: np.ndarray) -> None:
        watch.commanded(np.zeros(2), target, now=0.0, length_s=0.2)
        assert not watch.done(target - 0.1, running, now=0.1)
        watch.check(target - gap_rad, speed, now=1.21)

    watch.commanded(np.zeros(2), target, now=0.0, length_s=0.2)
    assert not watch.done(target - 0.1, running, now=0.1)
    assert not watch.done(target - 0.026, creeping, now=1.1)  # within the margin it may still arrive
    watch.check(target - 0.026, creeping, now=1.21)  # at its end, pressing: done, no fault
    assert watch.motion_time() == pytest.approx(1.21) and watch.gap == pytest.approx(0.026)
    pressed(0.002, creeping)  # trembling at its target, pushed by what it presses: done
    with pytest.raises(MotionUnfinished, match="fastest joint at 0.080 rad/s"):
        pressed(0.026, 4 * creeping)  # a third of its fastest: still on its way
    with pytest.raises(MotionUnfinished, match="still 0.080 rad"):
        pressed(0.08, np.array([0.0, 0.001]))
    watch.commanded(np.zeros(2), target, now=0.0, length_s=0.2)
    assert not watch.done(target - 0.04, creeping, now=0.5)  # never faster than it creeps now: driven slowly
    with pytest.raises(MotionUnfinished, match="fastest joint at 0.020 rad/s"):
        watch.check(target - 0.026, creeping, now=1.21)


def test_a_feed_is_stale_only_if_no_message_was_on_its_way():
    """A long computation of the env's own can keep the receiving thread from taking messages already on the
    socket: a message that lands within the grace after the limit is read, not taken for a dead feed; a feed
    with nothing more to deliver is still refused by name."""
    import threading
    import time

    from envfactory.backends.base import StaleFeed
    from envfactory.backends.rosbridge.feeds import RECEIVE_GRACE_S, Feed

    feed = Feed("/joint_states", 0.1, threading.Lock())
    feed.update((1.0,))
    time.sleep(0.15)  # past the limit, as after a long proof
    late = threading.Timer(RECEIVE_GRACE_S / 3, feed.update, ((2.0,),))
    late.start()
    values, _ = feed.fresh()
    late.join()
    assert values == (2.0,)
    time.sleep(0.15)
    with pytest.raises(StaleFeed, match=r"/joint_states is stale: newest message 0\.\d+ s old \(limit 0\.10 s\)"):
        feed.fresh()


def test_a_broken_message_landing_in_the_grace_is_the_reason_given():
    """Past the limit, the message that arrives within the grace may be a malformed one: the feed reports it
    as malformed (what is wrong), not as stale (what it looked like a moment earlier)."""
    import threading
    import time

    from envfactory.backends.base import MalformedFeed
    from envfactory.backends.rosbridge.feeds import RECEIVE_GRACE_S, Feed

    feed = Feed("/joint_states", 0.1, threading.Lock())
    feed.update((1.0,))
    time.sleep(0.15)
    broken = threading.Timer(RECEIVE_GRACE_S / 3, feed.fail, ("malformed message on /joint_states: position",))
    broken.start()
    with pytest.raises(MalformedFeed, match="malformed message on /joint_states: position"):
        feed.fresh()
    broken.join()
