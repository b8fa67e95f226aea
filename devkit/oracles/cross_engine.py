"""Each engine's steps judged by the other: where every accepted step leaves the simulated arm, measured with the
collision geometry of an engine that did not run the step and that the safety check does not use.

A PyBullet step's end pose is judged by MuJoCo's distance queries (mj_geomDistance) on the model MuJoCo's URDF
import builds of the same spec; a MuJoCo step's by PyBullet's (getClosestPoints, BulletJudge's second client).
The pose is copied joint by joint, by name, from the engine that ran the step (arm, gripper and every linkage
joint as simulated), so the judge sees the links where the step left them, not where they were commanded.
Both judges measure the robot's links against the scene's fixed obstacles (table, floor and the like).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pybullet as p

from devkit.oracles.bullet_judge import BulletJudge, drive_policy
from envfactory.backends.mujoco.model import ROBOT_PREFIX, ROBOT_TYPE, build


def simulated_joints(backend) -> dict[str, float]:
    """Every robot joint's simulated position, by its URDF name, from whichever engine runs the env."""
    if hasattr(backend, "model"):  # MuJoCo
        model, data = backend.model, backend.data
        values = {}
        for joint in range(model.njnt):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, joint) or ""
            hinge_or_slide = int(model.jnt_type[joint]) in (
                int(mujoco.mjtJoint.mjJNT_HINGE),
                int(mujoco.mjtJoint.mjJNT_SLIDE),
            )
            if name.startswith(ROBOT_PREFIX) and hinge_or_slide:
                values[name.removeprefix(ROBOT_PREFIX)] = float(data.qpos[model.jnt_qposadr[joint]])
        return values
    client, body = backend.client, backend.body
    values = {}
    for joint in range(p.getNumJoints(body, physicsClientId=client)):
        info = p.getJointInfo(body, joint, physicsClientId=client)
        if info[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
            values[info[1].decode()] = p.getJointState(body, joint, physicsClientId=client)[0]
    return values


def moving_robot_geoms(model) -> list[int]:
    """The robot's collision geoms on bodies a joint moves: those welded to the world (the base on its mount)
    never approach anything."""
    return [
        g
        for g in range(model.ngeom)
        if model.geom_contype[g] == ROBOT_TYPE and model.body_weldid[model.geom_bodyid[g]] != 0
    ]


def obstacle_geoms(model) -> list[int]:
    return [
        g
        for g in range(model.ngeom)
        if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith("obstacle:")
    ]


class MujocoJudge:
    """MuJoCo's distances from each moving robot collision geom to each fixed obstacle of the scene, in a model of
    its own (`for_env`: the one MuJoCo's URDF import builds of the env's spec) or one given."""

    def __init__(self, model, margin: float):
        self.model, self.margin = model, margin
        self.data = mujoco.MjData(model)
        self.robot_geoms, self.obstacles = moving_robot_geoms(model), obstacle_geoms(model)
        self.qpos_of = {}
        for joint in range(model.njnt):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, joint) or ""
            if name.startswith(ROBOT_PREFIX):
                self.qpos_of[name.removeprefix(ROBOT_PREFIX)] = int(model.jnt_qposadr[joint])

    @classmethod
    def for_env(cls, env, margin: float) -> "MujocoJudge":
        return cls(build(env.blueprint.spec, env.kinematics.urdf_path)[0], margin)

    def lowest(self, joints: dict[str, float]) -> tuple[float, str]:
        """The lowest clearance with the robot posed joint by joint by URDF name (below the margin, else inf)."""
        for name, value in joints.items():
            if name in self.qpos_of:
                self.data.qpos[self.qpos_of[name]] = value
        mujoco.mj_kinematics(self.model, self.data)
        return self.lowest_in(self.data)

    def lowest_in(self, data) -> tuple[float, str]:
        """The lowest clearance in `data`, posed already (below the margin, else inf), and between which geoms."""
        lowest, where = np.inf, (0, 0)
        for robot_geom in self.robot_geoms:
            for obstacle in self.obstacles:
                distance = mujoco.mj_geomDistance(self.model, data, robot_geom, obstacle, self.margin, None)
                if distance < min(lowest, self.margin):
                    lowest, where = distance, (robot_geom, obstacle)
        if lowest == np.inf:
            return lowest, ""
        return lowest, " / ".join(mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g) or str(g) for g in where)

    def close(self) -> None:
        pass


def other_engine_judge(env, margin: float):
    """The judge of the engine that did not run this env's steps: lowest(joints) -> (clearance, where)."""
    if hasattr(env.backend, "model"):  # MuJoCo ran them
        return BulletJudge(env, margin)
    return MujocoJudge.for_env(env, margin)


def judge_end_poses(env, policy_name: str, steps: int, seed: int = 0, episode_length: int = 25) -> dict:
    """Run a policy; after every accepted step, the other engine measures the simulated pose. Counts, the worst
    clearance seen, each step that ended inside the margin, and (PyBullet) how far any substep of an accepted
    step took a joint off the commanded straight line, in rad."""
    margin = env.blueprint.spec.env.safety.surface_margin
    judge = other_engine_judge(env, margin)
    result = {"violations": [], "lowest": np.inf, "off_line": None}
    line = _LineWatch(env.backend) if hasattr(env.backend, "_substep") else None

    def judged(step, state, command) -> None:
        value, what = judge.lowest(simulated_joints(env.backend))
        result["lowest"] = min(result["lowest"], value)
        if value < margin:
            result["violations"].append((step, round(float(value), 4), what))
        if line is not None:
            result["off_line"] = max(result["off_line"] or 0.0, line.worst)

    before = None if line is None else (lambda state, command: line.expect(state.q_arm, command.q_arm))
    try:
        result["accepted"], result["rejected"] = drive_policy(
            env, policy_name, steps, seed, episode_length, judged, before
        )
    finally:
        judge.close()
        if line is not None:
            line.close()
    return result


class _LineWatch:
    """PyBullet's arm after each substep against the straight joint-space line of the step's command."""

    def __init__(self, backend):
        self.backend, self._substep = backend, backend._substep
        backend._substep = self._watched
        self.start = self.way = None
        self.worst = 0.0

    def expect(self, start: np.ndarray, target: np.ndarray) -> None:
        self.start, self.way, self.worst = np.array(start, float), np.asarray(target, float) - start, 0.0

    def _watched(self) -> None:
        self._substep()
        backend, way = self.backend, self.way
        if way is None or not way.any():
            return
        states = p.getJointStates(backend.body, backend._arm, physicsClientId=backend.client)
        q = np.array([s[0] for s in states])
        fraction = np.clip((q - self.start) @ way / (way @ way), 0.0, 1.0)
        self.worst = max(self.worst, float(np.abs(q - (self.start + fraction * way)).max()))

    def close(self) -> None:
        self.backend._substep = self._substep
