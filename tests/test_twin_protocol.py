"""The twin's server behaves as a ROS 1 rosbridge_server (0.11) with rosapi does, seen
from a bare websocket client speaking the rosbridge v2 protocol: types are enforced per
topic, refusals stay in the server's log unless the client asked for status messages,
NaN goes out as null, and rosapi answers the topic services."""

import json
import math

import pytest
from websockets.sync.client import connect

from envfactory.twin import Twin, msgtypes

ARM = "/scaled_pos_joint_traj_controller/command"
JOINTS = "/ur5e/joint_states"
TRAJECTORY = "trajectory_msgs/JointTrajectory"


@pytest.fixture(scope="module")
def stand_in():
    twin = Twin("ur5e", "reach").start()
    yield twin
    twin.stop()


@pytest.fixture
def client(stand_in):
    with connect(f"ws://127.0.0.1:{stand_in.port}") as websocket:
        yield Client(websocket)


class Client:
    def __init__(self, websocket):
        self.websocket = websocket

    def send(self, **message):
        self.websocket.send(json.dumps(message))

    def next(self, op, timeout=2.0):
        """The next message with this op; TimeoutError if none comes."""
        while True:
            message = json.loads(self.websocket.recv(timeout=timeout))
            if message["op"] == op:
                return message

    def call(self, service, **args):
        self.send(op="call_service", id=f"call:{service}", service=service, args=args)
        return self.next("service_response")


def test_a_conflicting_advertise_is_refused_silently_until_a_level_is_set(stand_in, client):
    client.send(op="advertise", id="a1", topic=ARM, type="std_msgs/Float64MultiArray")
    client.send(op="publish", id="p1", topic=ARM, msg={"data": [1.0]})
    with pytest.raises(TimeoutError):
        client.next("status", timeout=0.3)  # the real server only logs it
    assert any("established with type " + TRAJECTORY in e for e in stand_in.server.errors)
    client.send(op="set_level", level="error")
    client.send(op="advertise", id="a2", topic=ARM, type="std_msgs/Float64MultiArray")
    status = client.next("status")
    assert status["level"] == "error" and status["id"] == "a2" and "std_msgs/Float64MultiArray" in status["msg"]
    assert not [r for r in stand_in.received if r.msg == {"data": [1.0]}]  # never reached the arm


@pytest.mark.parametrize(
    "msg, reason",
    [
        ({"joint_names": ["a"], "points": [], "velocity": 1}, "has no field 'velocity'"),
        ({"points": [{"positions": [None]}]}, "must be a number"),
        ({"points": [{"positions": 0.5}]}, "must be a list"),
        ({"joint_names": "shoulder_pan_joint"}, "must be a list"),
    ],
)
def test_a_publish_that_does_not_fill_the_type_is_refused(stand_in, client, msg, reason):
    before = len(stand_in.received)
    client.send(op="set_level", level="error")
    client.send(op="publish", id="p", topic=ARM, msg=msg)
    assert reason in client.next("status")["msg"]
    assert len(stand_in.received) == before


def test_a_publish_on_an_unknown_topic_needs_an_advertise(client):
    client.send(op="set_level", level="error")
    client.send(op="publish", id="p", topic="/nobody", msg={"data": 1.0})
    assert "cannot infer the type of /nobody" in client.next("status")["msg"]


def test_nan_goes_out_as_null(stand_in, client):
    client.send(op="subscribe", id="s", topic=JOINTS, type="sensor_msgs/JointState")
    client.next("publish")  # subscribed: the one broken message cannot go out before anyone listens
    stand_in.faults.corrupt(JOINTS, 1)
    for _ in range(100):  # the twin publishes at its driver's rate; the broken one is among the next few
        msg = client.next("publish")["msg"]
        if None in msg["position"]:
            break
    assert msg["position"][-1] is None and all(v is not None for v in msg["position"][:-1])
    assert msgtypes.nulls_for_non_finite({"a": [1.0, math.inf, -math.inf]}) == {"a": [1.0, None, None]}


def test_rosapi_answers_the_topic_services(stand_in, client):
    reply = client.call("/rosapi/topic_type", topic=ARM)
    assert reply["result"] is True and reply["values"] == {"type": TRAJECTORY}
    assert client.call("/rosapi/topic_type", topic="/nobody")["values"] == {"type": ""}
    assert client.call("/rosapi/subscribers", topic=ARM)["values"] == {"subscribers": ["/ur5e_driver"]}
    assert client.call("/rosapi/publishers", topic=JOINTS)["values"] == {"publishers": ["/ur5e_driver"]}
    topics = client.call("/rosapi/topics")["values"]
    assert dict(zip(topics["topics"], topics["types"]))[JOINTS] == "sensor_msgs/JointState"
    assert ARM in client.call("/rosapi/topics_for_type", type=TRAJECTORY)["values"]["topics"]
    missing = client.call("/rosapi/no_such_service")
    assert missing["result"] is False and "does not exist" in missing["values"]


def test_a_bridge_subscription_shows_in_rosapi(client):
    client.send(op="subscribe", id="s", topic=ARM, type=TRAJECTORY)
    assert "/rosbridge_websocket" in client.call("/rosapi/subscribers", topic=ARM)["values"]["subscribers"]


def test_without_rosapi_its_services_do_not_exist(stand_in, client):
    stand_in.faults.no_rosapi = True
    try:
        assert client.call("/rosapi/topic_type", topic=ARM)["result"] is False
    finally:
        stand_in.faults.no_rosapi = False
