"""Mistakes a user makes in a copy of the shipped specs, one edit each, that validate used to pass (and the expert
then ran at 0%, or register died later) or reported without saying where: each is now refused with the file and
line (or the folder and the files involved), the dotted path, and what to do."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from typer.testing import CliRunner

import envfactory
from envfactory.backends.base import BackendError
from envfactory.cli.app import app
from envfactory.factory import register_specs, unregister_folder
from envfactory.geometry.collision_pairs import checksum, write_pairs
from envfactory.schema.errors import SpecError

ROOT = Path(__file__).parents[1]
runner = CliRunner()


def user_folder(tmp_path: Path, family: str, robot: str | None = None, edits=()) -> Path:
    """A spec folder holding a copy of one shipped family, whose simulated ID is renamed My<ID> and kept alone (the
    built-in IDs stay registered), and of the shipped robot YAML and its assets when `robot` is named; `edits` are
    the user's mistake: (file relative to the folder, old text, new text)."""
    folder = tmp_path / "mine"
    (folder / "specs").mkdir(parents=True)
    text = (ROOT / "specs" / f"{family}.yaml").read_text()
    sim_id = re.search(r"^    (\w+Sim-v0):", text, re.M).group(1)
    text = text[: text.index("registration:")] + f"registration:\n  ids:\n    My{sim_id}: {{backend: sim}}\n"
    (folder / "specs" / f"{family}.yaml").write_text(text)
    if robot is not None:
        (folder / "robots").mkdir()
        shutil.copy(ROOT / "robots" / f"{robot}.yaml", folder / "robots")
        shutil.copytree(ROOT / "robots" / "assets", folder / "robots" / "assets")
    for name, old, new in edits:
        path = folder / name
        assert old in path.read_text(), f"{name} no longer holds {old!r}: update the test's edit"
        path.write_text(path.read_text().replace(old, new, 1))
    return folder


def line_of(path: Path, text: str) -> int:
    return next(number for number, row in enumerate(path.read_text().splitlines(), 1) if text in row)


def refusal(folder: Path) -> str:
    """The one problem registering the folder reports (nothing of it registers), on one line."""
    before = set(envfactory.records())
    added, problems = register_specs(folder)
    assert added == [] and set(envfactory.records()) == before
    assert len(problems) == 1, problems
    return " ".join(str(problems[0]).split())


def validate(*paths: Path) -> tuple[int, str]:
    result = runner.invoke(app, ["validate", *map(str, paths)])
    return result.exit_code, " ".join(result.output.split())


# ---------------------------------------------------------------- silent 0% experts


def test_world_frame_goal_heights_in_a_base_frame_robot(tmp_path):
    """The VX300S takes goals in its base frame; world heights put the goal box ~0.8 m above the table, within
    the arm's reach, where the expert never carries the cube."""
    shipped = "box: [[0.20, -0.20, 0.025], [0.35, 0.20, 0.25]]"
    folder = user_folder(
        tmp_path,
        "vx300s_pnp",
        edits=[("specs/vx300s_pnp.yaml", shipped, "box: [[0.15, -0.10, 0.795], [0.25, 0.10, 0.85]]")],
    )
    message = refusal(folder)
    family = folder / "specs" / "vx300s_pnp.yaml"
    assert (
        f"{family}:{line_of(family, 'box:')}: task.goal.box: goal box bottom z 0.795 lies 0.8 m above the table "
        f"top (z -0.005 in the base frame)" in message
    )
    assert "look like world-frame heights" in message and "subtract 0.78 from every z" in message


@pytest.mark.parametrize(
    "family, shipped, pasted, expected",
    [
        (
            "vx300s_pnp",
            "spawn: {position: [0.25, 0.0, 0.015]}",
            "spawn: {position: [0.25, 0.0, 0.795]}",
            "task.objects.cube.spawn.position: cube centre z 0.795 floats 0.78 m above the table: "
            "resting on the top it is "
            "at z 0.015; these look like world-frame heights",
        ),
        (
            "ur5e_pnp",
            "box: [[0.40, -0.30, 0.795], [0.80, 0.30, 0.95]]",
            "box: [[0.40, -0.30, 0.205], [0.80, 0.30, 0.36]]",
            "task.goal.box: goal box bottom z 0.205 lies below the table top (z 0.775 in the world frame); valid: z >= "
            "0.775; these look like base-frame heights: robot 'ur5e' gives goals and spawns in the world frame "
            "(task_frame: world), where its base is 0.59 m up (robot.mount) and the table top at z 0.775: add 0.59",
        ),
    ],
)
def test_heights_pasted_from_the_other_frame_are_named(tmp_path, family, shipped, pasted, expected):
    folder = user_folder(tmp_path, family, edits=[(f"specs/{family}.yaml", shipped, pasted)])
    path = folder / "specs" / f"{family}.yaml"
    assert f"{path}:{line_of(path, pasted.split(':')[0] + ':')}: {expected}" in refusal(folder)


def test_object_goal_far_above_the_table(tmp_path):
    shipped = "box: [[0.40, -0.30, 0.795], [0.80, 0.30, 0.95]]"
    folder = user_folder(
        tmp_path,
        "ur5e_pnp",
        edits=[("specs/ur5e_pnp.yaml", shipped, "box: [[0.40, -0.30, 0.795], [0.80, 0.30, 1.40]]")],
    )
    message = refusal(folder)
    family = folder / "specs" / "ur5e_pnp.yaml"
    assert (
        f"{family}:{line_of(family, 'box:')}: task.goal.box: goal box top z 1.4 lies 0.625 m above the table" in message
    )
    assert "out of any pick-and-place task; valid: z <= 1.27" in message


def test_validate_and_describe_print_goal_and_spawn_heights(tmp_path):
    folder = user_folder(tmp_path, "vx300s_pnp")
    code, output = validate(folder)
    assert code == 0, output
    heights = (
        "Heights above the table top (z -0.005 in the base frame): goal 0.030–0.255 m, cube centre 0.020 m "
        "(resting: 0.02)"
    )
    assert f"vx300s_pnp: 1 ID(s) valid. {heights}" in output
    described = runner.invoke(app, ["describe", "VX300SPnPSim-v0"])
    assert described.exit_code == 0 and heights in " ".join(described.output.split())


def test_gripper_open_and_closed_swapped(tmp_path):
    folder = user_folder(
        tmp_path,
        "vx300s_pnp",
        robot="vx300s",
        edits=[("robots/vx300s.yaml", "open: 0.057\n  closed: 0.021", "open: 0.021\n  closed: 0.057")],
    )
    message = refusal(folder)
    robot = folder / "robots" / "vx300s.yaml"
    assert (
        f"{robot}:{line_of(robot, 'closed: 0.057')}: robot.gripper.closed: open (0.021) and closed (0.057) look "
        f"swapped" in message
    )
    assert "left_finger_link and right_finger_link are 42.0 mm apart at open and 114.0 mm at closed" in message
    assert "close toward smaller values of left_finger); swap the two values" in message
    assert "stale" not in message  # the pair list's fingerprint changed too, but that is not the mistake


def test_workspace_floor_above_the_grasp_point(tmp_path):
    """In EE mode the EE never goes below the workspace floor: 6 cm is above the grasp point (4.7 cm)."""
    folder = user_folder(
        tmp_path,
        "vx300s_pnp",
        edits=[
            ("specs/vx300s_pnp.yaml", "workspace: {min: [0.10, -0.85, 0.04]", "workspace: {min: [0.10, -0.85, 0.06]")
        ],
    )
    message = refusal(folder)
    family = folder / "specs" / "vx300s_pnp.yaml"
    assert (
        f"{family}:{line_of(family, 'workspace:')}: workspace.min: the expert's grasp point z 0.047 (the "
        f"object's centre z 0.015 + 0.032) lies below the workspace floor (workspace.min z 0.06)" in message
    )
    assert "in EE mode (ee_action_type) the EE is never commanded outside the workspace" in message
    assert f"task.expert.params.grasp_height ({family}:{line_of(family, 'grasp_height')})" in message


def test_grasp_point_inside_the_safety_margin(tmp_path):
    """A grasp height that brings the Robotiq fingertips within the table's margin: the safety check refuses that
    pose every time, and the expert stalls above the cube."""
    folder = user_folder(
        tmp_path, "ur5e_pnp", edits=[("specs/ur5e_pnp.yaml", "grasp_height: 0.034", "grasp_height: 0.01")]
    )
    message = refusal(folder)
    family = folder / "specs" / "ur5e_pnp.yaml"
    assert (
        f"{family}:{line_of(family, 'grasp_height')}: task.expert.params.grasp_height: the expert's grasp point "
        f"[0.5, -0.15, 0.805] (the object's centre z 0.795 + 0.01) is a pose the safety check refuses" in message
    )
    assert "of table top" in message and "valid: a higher grasp_height" in message


# ---------------------------------------------------------------- accepted though dangerous or absurd


def test_pair_list_entry_naming_no_shape(tmp_path):
    """A skipped pair added to a copied list, its checksum brought up to date: the entry used to be ignored."""
    folder = user_folder(tmp_path, "vx300s_pnp", robot="vx300s")
    pairs = folder / "robots" / "assets" / "vx300s.collision.yaml"
    data = yaml.safe_load(pairs.read_text())
    data["skipped"].append(["wrist_lnk_0", "gripper_link_0", "rigidly joined"])
    data["checksum"] = checksum(data)
    write_pairs(pairs, "vx300s", data)
    message = refusal(folder)
    robot = folder / "robots" / "vx300s.yaml"
    assert (
        f"{robot}:{line_of(robot, 'collision_pairs:')}: robot.safety.collision_pairs: {pairs}:"
        f"{line_of(pairs, 'wrist_lnk_0')}: the collision pair list names collision shapes robot 'vx300s' does not "
        f"have: skipped entry" in message
    )
    assert "no shape 'wrist_lnk_0' (did you mean 'wrist_link_0'?)" in message


def test_delta_wider_than_the_joints_range(tmp_path):
    folder = user_folder(
        tmp_path,
        "vx300s_pnp",
        robot="vx300s",
        edits=[("robots/vx300s.yaml", "delta: [-1.85, 1.26]", "delta: [-6.0, 6.0]")],
    )
    message = refusal(folder)
    robot = folder / "robots" / "vx300s.yaml"
    assert (
        f"{robot}:{line_of(robot, 'delta: [-6.0, 6.0]')}: robot.arm_joints.1.delta: delta [-6.0, 6.0] rad allows "
        f"a step of 6 rad, larger than the joint's whole range [-1.85, 1.26] (3.11 rad)" in message
    )


def test_physics_rate_too_low(tmp_path):
    folder = user_folder(tmp_path, "ur5e_pnp", edits=[("specs/ur5e_pnp.yaml", "sim:\n", "sim:\n  physics_hz: 1\n")])
    message = refusal(folder)
    family = folder / "specs" / "ur5e_pnp.yaml"
    assert (
        f"{family}:{line_of(family, 'physics_hz')}: sim.physics_hz: physics rate 1 Hz is too low to simulate this "
        f"robot" in message
    )
    assert "needs at least 20 physics steps (100 Hz)" in message and "valid: physics_hz >= 100" in message


# ---------------------------------------------------------------- passed validate, then failed


def test_gui_without_a_display_is_refused_at_make(monkeypatch, tmp_path):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(SpecError) as error:
        gym.make("UR5eReacherSim-v0", gui=True)
    message = " ".join(str(error.value).split())
    assert (
        "gym.make kwarg gui=True: env.gui: gui=True opens PyBullet's window, and this machine has no display" in message
    )
    folder = user_folder(
        tmp_path,
        "vx300s_reach",
        edits=[("specs/vx300s_reach.yaml", "registration:", "env: {gui: true}\nregistration:")],
    )
    family = folder / "specs" / "vx300s_reach.yaml"
    assert f"{family}:{line_of(family, 'gui: true')}: env.gui: gui=True opens PyBullet's window" in refusal(folder)


def test_render_mode_human_without_a_display_is_refused_at_make(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(
        BackendError, match="render_mode='human' opens PyBullet's window, and this machine has no display"
    ):
        gym.make("UR5eReacherSim-v0", render_mode="human")


def test_a_family_file_given_as_a_folder(tmp_path):
    folder = user_folder(tmp_path, "vx300s_reach")
    family = folder / "specs" / "vx300s_reach.yaml"
    added, problems = register_specs(family)
    assert added == [] and len(problems) == 1
    assert f"{family}: is a file, not a spec folder" in str(
        problems[0]
    ) and f"the folder that holds it, {folder}" in str(problems[0])
    code, output = validate(family)
    assert (
        code == 0
        and f"note: {family} is a family file; `envfactory register` and ENVFACTORY_SPEC_PATH take its "
        f"spec folder, {folder}"
        in output
    )


def test_a_family_at_the_root_of_a_folder_with_specs(tmp_path):
    """The folder's families are in specs/; a second one saved beside specs/ used to be passed over in silence."""
    folder = user_folder(tmp_path, "vx300s_reach")
    extra = folder / "vx300s_reach_too.yaml"
    extra.write_text((folder / "specs" / "vx300s_reach.yaml").read_text().replace("MyVX300S", "MyOtherVX300S"))
    try:
        added, problems = register_specs(folder)
    finally:
        unregister_folder(folder)
    assert added == ["MyVX300SReacherSim-v0"] and len(problems) == 1
    message = " ".join(str(problems[0]).split())
    assert f"{extra}: a family file at the folder's root is not read: {folder} has a specs/ folder" in message
    assert f"move it into {folder / 'specs'}" in message
    code, output = validate(folder)
    assert code == 1 and f"{extra}: a family file at the folder's root is not read" in output


# ---------------------------------------------------------------- refused without a file or line


def test_an_empty_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    code, output = validate(tmp_path / "empty")
    assert code == 1 and f"{tmp_path / 'empty'}: the folder is empty: a spec folder holds family files" in output
    assert f"{tmp_path / 'empty'}: the folder is empty" in refusal(tmp_path / "empty")


def test_skipped_files_are_named_with_why(tmp_path):
    folder = user_folder(tmp_path, "vx300s_reach")
    family = folder / "specs" / "vx300s_reach.yaml"
    shutil.copy(family, folder / "specs" / "_draft.yaml")
    family.rename(family.with_suffix(".yml"))
    code, output = validate(folder)
    assert (
        code == 1
        and f"no family files (*.yaml) to read in {folder / 'specs'}; skipped specs/_draft.yaml: a "
        f"leading underscore marks a shared file"
        in output
    )
    assert "specs/vx300s_reach.yml: family files end in .yaml: rename it to vx300s_reach.yaml" in output


def test_a_path_that_does_not_exist(tmp_path):
    user_folder(tmp_path, "vx300s_reach")
    code, output = validate(tmp_path / "mnie")
    assert code == 1 and f"{tmp_path / 'mnie'}: no such file or folder (did you mean 'mine'?)" in output
    added, problems = register_specs(tmp_path / "mnie")
    assert added == [] and "no such spec folder (did you mean 'mine'?)" in str(problems[0])


def test_a_family_without_the_shared_defaults(tmp_path):
    folder = user_folder(
        tmp_path, "vx300s_reach", edits=[("specs/vx300s_reach.yaml", "  - /specs/_defaults@_here_\n", "")]
    )
    message = refusal(folder)
    family = folder / "specs" / "vx300s_reach.yaml"
    assert (
        f"{family}:{line_of(family, 'defaults:')}: scene: missing value; no file of this defaults list sets "
        f"'scene': the shared defaults do, and the list lacks them: add '- /specs/_defaults@_here_' to it" in message
    )


@pytest.mark.parametrize(
    "entry, wrong, right", [("/specs/_defaults@_hre_", "_hre_", "_here_"), ("/robots@robt: vx300s", "robt", "robot")]
)
def test_a_misspelled_defaults_package(tmp_path, entry, wrong, right):
    shipped = {"_hre_": "/specs/_defaults@_here_", "robt": "/robots@robot: vx300s"}[wrong]
    folder = user_folder(tmp_path, "vx300s_reach", edits=[("specs/vx300s_reach.yaml", shipped, entry)])
    message = refusal(folder)
    family = folder / "specs" / "vx300s_reach.yaml"
    assert f"{family}:{line_of(family, entry)}: defaults: package {wrong!r}" in message
    assert f"(did you mean {right!r}?)" in message and "missing value" not in message


def test_a_misspelled_defaults_file(tmp_path):
    folder = user_folder(
        tmp_path,
        "vx300s_reach",
        edits=[("specs/vx300s_reach.yaml", "/specs/_defaults@_here_", "/specs/_defualts@_here_")],
    )
    family = folder / "specs" / "vx300s_reach.yaml"
    assert (
        f"{family}:{line_of(family, '_defualts')}: defaults: no config '/specs/_defualts' found (did you mean "
        f"'/specs/_defaults'?)" in refusal(folder)
    )


def test_a_gripper_task_on_a_robot_without_a_gripper(tmp_path):
    folder = user_folder(tmp_path, "vx300s_pnp", robot="vx300s")
    robot = folder / "robots" / "vx300s.yaml"
    text = robot.read_text()
    robot.write_text(text[: text.index("\ngripper:\n")] + text[text.index("\nsafety:\n") :])  # the gripper block cut
    message = refusal(folder)
    family = folder / "specs" / "vx300s_pnp.yaml"
    assert (
        f"{family}:{line_of(family, '/robots@robot')}: robot.gripper: task 'pnp' drives a gripper (in its "
        f"action, task.gripper) but robot 'vx300s' declares none" in message
    )
    assert f"(not written in {robot}; this defaults line chose that file)" in message


# ---------------------------------------------------------------- also


def test_padding_on_a_shipped_robot_says_what_changed_and_never_to_rewrite_the_package(tmp_path):
    folder = user_folder(
        tmp_path,
        "ur5e_pnp",
        edits=[
            (
                "specs/ur5e_pnp.yaml",
                "registration:",
                "robot:\n  safety:\n    padding: {wrist_3_link: 0.01}\nregistration:",
            )
        ],
    )
    message = refusal(folder)
    family = folder / "specs" / "ur5e_pnp.yaml"
    shipped = ROOT / "robots" / "ur5e.yaml"
    assert f"{shipped}:{line_of(shipped, 'collision_pairs:')}: robot.safety.collision_pairs:" in message
    assert (
        "what changed: padding (robot.safety.padding): wrist_3_link +0.01 m added since the list was generated"
        f" (it was made without padding) (written at {family}:{line_of(family, 'padding:')})" in message
    )
    own = folder.resolve() / "robots" / "ur5e.collision.yaml"
    assert "belongs to the installed envfactory package" in message and "do not rewrite it" in message
    assert f"point the robot at it in {family} with `robot: {{safety: {{collision_pairs: {own}}}}}`" in message
    assert f"`envfactory collision-pairs MyUR5ePnPSim-v0 --specs {folder.resolve()}`" in message
    assert "`envfactory collision-pairs ur5e`" not in message


def test_following_the_padding_advice_validates(tmp_path):
    """The advice works as written: the list goes into the user's folder, the shipped one is left as it was."""
    shipped = (ROOT / "robots" / "assets" / "ur5e.collision.yaml").read_text()
    folder = user_folder(
        tmp_path,
        "ur5e_pnp",
        edits=[
            (
                "specs/ur5e_pnp.yaml",
                "registration:",
                "robot:\n  safety:\n    padding: {wrist_3_link: 0.01}\n"
                f"    collision_pairs: {tmp_path / 'mine' / 'robots' / 'ur5e.collision.yaml'}\n"
                "registration:",
            )
        ],
    )
    try:
        written = runner.invoke(app, ["collision-pairs", "MyUR5ePnPSim-v0", "--specs", str(folder), "--samples", "200"])
        assert written.exit_code == 0, written.output
    finally:
        unregister_folder(folder)
    assert (folder / "robots" / "ur5e.collision.yaml").is_file()
    assert (ROOT / "robots" / "assets" / "ur5e.collision.yaml").read_text() == shipped
    try:
        added, problems = register_specs(folder)
        assert problems == [] and added == ["MyUR5ePnPSim-v0"]
    finally:
        unregister_folder(folder)


def test_a_misspelled_override_gets_a_did_you_mean():
    with pytest.raises(SpecError) as error:
        envfactory.blueprint("UR5eReacherSim-v0", ["task.goal.tolerence=0.1"])
    assert (
        "override 'task.goal.tolerence=0.1': task.goal.tolerence: no key 'tolerence' under 'task.goal' of the spec "
        "(did you mean 'task.goal.tolerance'?)" in str(error.value)
    )


def test_lengths_in_centimetres_and_angles_in_degrees_are_named(tmp_path):
    folder = user_folder(
        tmp_path,
        "ur5e_reach",
        edits=[
            (
                "specs/ur5e_reach.yaml",
                "box: [[0.40, -0.30, 0.85], [0.80, 0.30, 1.10]]",
                "box: [[40, -30, 85], [80, 30, 110]]",
            )
        ],
    )
    message = refusal(folder)
    family = folder / "specs" / "ur5e_reach.yaml"
    assert (
        f"{family}:{line_of(family, 'box:')}: task.goal.box.0.2: Input should be less than or equal to 10 (got 85; "
        f"looks like centimetres: lengths are in metres (85 cm = 0.85 m))" in message
    )
    folder = user_folder(
        tmp_path / "degrees",
        "ur5e_reach",
        robot="ur5e",
        edits=[
            (
                "robots/ur5e.yaml",
                "home: [0.0, -1.5707, 1.5707, -1.5707, -1.5707, 0.0]",
                "home: [0, -90, 90, -90, -90, 0]",
            )
        ],
    )
    robot = folder / "robots" / "ur5e.yaml"
    message = refusal(folder)
    assert (
        f"{robot}:{line_of(robot, 'home:')}: robot.home.1: home value -90.0 of shoulder_lift_joint is outside "
        f"[-3.14, 3.14]; looks like degrees: angles are in radians (-90° = -1.571 rad)" in message
    )


def test_the_old_backend_spelling_registers_a_simulated_id_with_a_deprecation_note(tmp_path):
    """`backend: pybullet` was how a simulated ID registered whichever engine ran it: it still does, as `sim`,
    and says so; the ID makes and steps on the spec's engine."""
    folder = user_folder(
        tmp_path, "ur5e_reach", edits=[("specs/ur5e_reach.yaml", "{backend: sim}", "{backend: pybullet}")]
    )
    try:
        with pytest.warns(DeprecationWarning, match="registration backend 'pybullet' is the old spelling of 'sim'"):
            added, problems = register_specs(folder)
        assert problems == [] and added == ["MyUR5eReacherSim-v0"]
        assert envfactory.records()["MyUR5eReacherSim-v0"].backend == "sim"
        env = gym.make("MyUR5eReacherSim-v0", engine="mujoco")
        try:
            assert env.unwrapped.blueprint.backend == "mujoco"
            env.reset(seed=0)
            env.step(env.action_space.sample())
        finally:
            env.close()
    finally:
        unregister_folder(folder)
