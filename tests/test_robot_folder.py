"""A user's own robot: its URDF and meshes are found (package:// through declared packages),
or validate says which file is missing and where the spec names it."""

from __future__ import annotations

import re
import shutil
import struct
from pathlib import Path

import gymnasium as gym
import pytest

from envfactory.factory import register_specs, unregister_folder

ROOT = Path(__file__).parents[1]
# A binary STL with one triangle: the smallest mesh PyBullet and Pinocchio both load.
TRIANGLE_STL = b"\0" * 80 + struct.pack("<I12fH", 1, 0, 0, 1, 0, 0, 0, 0.05, 0, 0, 0, 0.05, 0, 0)


def _robot_folder(tmp_path: Path, packages: str = "", urdf: str = "assets/arm.urdf") -> Path:
    folder = tmp_path / "robotdir"
    (folder / "robots" / "assets").mkdir(parents=True)
    (folder / "specs").mkdir()
    (folder / "meshes").mkdir()
    (folder / "meshes" / "base.stl").write_bytes(TRIANGLE_STL)
    text = (ROOT / "robots" / "assets" / "vx300s.urdf").read_text()
    # the base link's visual becomes a package:// mesh
    text = re.sub(
        r"<visual>(.*?)<geometry>.*?</geometry>",
        lambda m: (
            m.group(0).split("<geometry>")[0]
            + '<geometry><mesh filename="package://arm_description/meshes/base.stl"/></geometry>'
        ),
        text,
        count=1,
        flags=re.S,
    )
    (folder / "robots" / "assets" / "arm.urdf").write_text(text)
    robot = (ROOT / "robots" / "vx300s.yaml").read_text().replace("name: vx300s", "name: myarm")
    robot = robot.replace("urdf: assets/vx300s.urdf", f"urdf: {urdf}").replace("model:\n", f"model:\n{packages}", 1)
    # the shipped pair list belongs to the shipped URDF: this robot measures every pair instead
    robot = re.sub(r"safety:\n  collision_pairs: .*\n", "", robot)
    (folder / "robots" / "myarm.yaml").write_text(robot)
    family = (ROOT / "specs" / "vx300s_reach.yaml").read_text().replace("/robots@robot: vx300s", "/robots@robot: myarm")
    family = re.sub(r"registration:.*", "registration:\n  ids: {MyArmReach-v0: {backend: sim}}\n", family, flags=re.S)
    (folder / "specs" / "myarm_reach.yaml").write_text(family)
    return folder


def test_package_mesh_resolves_through_declared_packages(tmp_path):
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    try:
        added, problems = register_specs(folder)
        assert problems == [] and added == ["MyArmReach-v0"]
        env = gym.make("MyArmReach-v0")
        env.reset(seed=0)
        env.close()
    finally:
        unregister_folder(folder)


def test_undeclared_package_is_named_with_the_robot_file_and_line(tmp_path):
    folder = _robot_folder(tmp_path)
    added, problems = register_specs(folder)
    assert added == []
    message = str(problems[0])
    assert "myarm.yaml:" in message and "package://arm_description/meshes/base.stl" in message
    assert "declare its package" in message


def test_an_undeclared_package_beside_the_urdf_is_read_from_there(tmp_path):
    """As PyBullet reads pybullet_data's Panda (`package://meshes/...` beside its URDF)."""
    folder = _robot_folder(tmp_path)
    beside = folder / "robots" / "assets" / "arm_description" / "meshes"
    beside.mkdir(parents=True)
    (beside / "base.stl").write_bytes(TRIANGLE_STL)
    try:
        added, problems = register_specs(folder)
        assert problems == [] and added == ["MyArmReach-v0"]
    finally:
        unregister_folder(folder)


def test_a_pybullet_data_part_that_is_not_installed_is_named(tmp_path):
    folder = _robot_folder(tmp_path)
    robot = folder / "robots" / "myarm.yaml"
    robot.write_text(robot.read_text().replace("urdf: assets/arm.urdf", "pybullet_data: nope/arm.urdf"))
    added, problems = register_specs(folder)
    assert added == [] and len(problems) == 1
    message = str(problems[0])
    assert "myarm.yaml:" in message, message
    assert "robot.model.parts.0.pybullet_data: the installed pybullet_data has no 'nope/arm.urdf'" in message, message


@pytest.mark.parametrize(
    "broken, expected",
    [
        ("missing_urdf", "robot.model.parts.0.urdf: no URDF file at"),
        ("missing_mesh", "mesh 'package://arm_description/meshes/base.stl' in arm.urdf not found"),
    ],
)
def test_missing_files_are_named(tmp_path, broken, expected):
    urdf = "assets/nope.urdf" if broken == "missing_urdf" else "assets/arm.urdf"
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n", urdf=urdf)
    if broken == "missing_mesh":
        shutil.rmtree(folder / "meshes")
    added, problems = register_specs(folder)
    assert added == [] and len(problems) == 1
    assert "myarm.yaml:" in str(problems[0]) and expected in str(problems[0]), str(problems[0])


def test_collision_pairs_rewrites_a_stale_list(tmp_path):
    """A stale pair list makes every ID of the robot invalid; the command that rewrites it must
    still find the robot."""
    import os
    import subprocess
    import sys

    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    robot = folder / "robots" / "myarm.yaml"
    robot.write_text(robot.read_text() + "safety:\n  collision_pairs: assets/myarm.collision.yaml\n")
    pairs = folder / "robots" / "assets" / "myarm.collision.yaml"
    pairs.write_text(
        (ROOT / "robots" / "assets" / "vx300s.collision.yaml")
        .read_text()
        .replace("fingerprint:", "fingerprint: stale", 1)
    )
    env = {**os.environ, "ENVFACTORY_SPEC_PATH": str(folder)}
    cli = str(Path(sys.executable).parent / "envfactory")

    def run(*args):
        return subprocess.run([cli, *args], env=env, capture_output=True, text=True, timeout=300)

    before = run("validate", str(folder))
    assert before.returncode == 1 and "stale" in before.stderr + before.stdout
    written = run("collision-pairs", "myarm", "--samples", "200")
    assert written.returncode == 0, written.stderr + written.stdout
    assert "stale" not in pairs.read_text()
    after = run("validate", str(folder))
    assert after.returncode == 0, after.stderr + after.stdout


def test_library_names_no_robot_added_as_yaml():
    """The RX200 and Ned2 came as robot YAML, URDF and family files only: no library file knows them."""
    added = [yaml_file.stem for yaml_file in (ROOT / "robots").glob("*.yaml") if yaml_file.stem in ("rx200", "ned2")]
    assert sorted(added) == ["ned2", "rx200"]
    for source in (ROOT / "envfactory").rglob("*.py"):
        text = source.read_text().lower()
        assert not any(name in text for name in added), f"{source} names one of {added}"


def test_collision_pairs_writes_a_missing_list(tmp_path):
    """A new robot has no pair list yet: the command writes the file its YAML names, and the folder validates."""
    import os
    import subprocess
    import sys

    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    robot = folder / "robots" / "myarm.yaml"
    robot.write_text(robot.read_text() + "safety:\n  collision_pairs: assets/myarm.collision.yaml\n")
    pairs = folder / "robots" / "assets" / "myarm.collision.yaml"
    assert not pairs.exists()
    env = {**os.environ, "ENVFACTORY_SPEC_PATH": str(folder)}
    cli = str(Path(sys.executable).parent / "envfactory")

    def run(*args):
        return subprocess.run([cli, *args], env=env, capture_output=True, text=True, timeout=300)

    assert run("validate", str(folder)).returncode == 1
    written = run("collision-pairs", "myarm", "--samples", "200")
    assert written.returncode == 0, written.stderr + written.stdout
    assert pairs.is_file()
    after = run("validate", str(folder))
    assert after.returncode == 0, after.stderr + after.stdout


def test_a_simulation_only_robot_needs_no_ros_section(tmp_path):
    """A robot without a real path declares no topics: its Sim IDs register, make and step; a Real ID on it is
    refused by name."""
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    robot = folder / "robots" / "myarm.yaml"
    text = re.sub(r"^ros:.*\n(?:[ #].*\n|\n)*", "", robot.read_text(), flags=re.M)
    robot.write_text(re.sub(r"^joint_states_topic:.*\n", "", text, flags=re.M))
    assert "ros:" not in robot.read_text() and "topic" not in robot.read_text()
    try:
        added, problems = register_specs(folder)
        assert problems == [] and added == ["MyArmReach-v0"]
        env = gym.make("MyArmReach-v0")
        env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()
    finally:
        unregister_folder(folder)
    family = folder / "specs" / "myarm_reach.yaml"
    family.write_text(family.read_text().replace("{backend: sim}", "{backend: rosbridge}"))
    added, problems = register_specs(folder)
    assert added == [] and "robot 'myarm' declares no 'ros:' block" in str(problems[0])


def _two_links(ixx: float, iyy: float, izz: float) -> str:
    return f"""<robot name="probe">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="arm">
    <inertial><mass value="1"/><inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


@pytest.mark.parametrize("moments", [(0.1, 0.001, 0.001), (0.002, 0.002, 0.002), (0.01, 0.01, 0.02)])
def test_inertias_are_judged_as_mujoco_judges_them(tmp_path, moments):
    """The oracle is MuJoCo's own compiler: a body it refuses is refused at validate, one it takes passes."""
    mujoco = pytest.importorskip("mujoco")
    from envfactory.compiler.inertia_checks import inertia_problems

    urdf = tmp_path / "probe.urdf"
    urdf.write_text(_two_links(*moments))
    try:
        mujoco.MjModel.from_xml_string(urdf.read_text())
        engine_refuses = False
    except ValueError:
        engine_refuses = True
    problems = inertia_problems(urdf)
    assert bool(problems) == engine_refuses, (moments, problems)
    if problems:
        assert problems[0].startswith(f"{urdf}:4: link 'arm': principal moments") and "triangle" in problems[0]


def test_a_robot_whose_urdf_breaks_an_inertia_is_refused_at_validate(tmp_path):
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    urdf = folder / "robots" / "assets" / "arm.urdf"
    text = urdf.read_text()
    first = re.search(r'<inertia ixx="[^"]*"', text)
    urdf.write_text(text[: first.start()] + '<inertia ixx="5.0"' + text[first.end() :])
    added, problems = register_specs(folder)
    assert added == []
    message = " ".join(str(problems[0]).split())
    assert (
        "robot.model.parts.0.urdf" in message and "arm.urdf:" in message and "break the triangle inequality" in message
    )
