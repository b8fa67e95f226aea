"""An independent judge of the safety check: PyBullet's own distance queries.

It measures the simulated scene after each step, and the commanded motion posed
in a second PyBullet client, with Bullet's collision shapes (convex hulls of the
URDF meshes) rather than the check's Pinocchio/coal model.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from envfactory.geometry.obstacles import scene_obstacles


class BulletJudge:
    """Clearances of every robot link from every obstacle and from its non-exempt links."""

    def __init__(self, env, margin: float):
        self.env = env
        self.margin = margin
        backend = env.backend
        if hasattr(backend, "client"):  # PyBullet runs the env: its scene can be measured in place
            self.sim_client, self.sim_body = backend.client, backend.body
            self.sim_obstacles = list(backend.obstacle_bodies)
        # a second client holds the same robot and scene, posed along commanded motions
        self.client = p.connect(p.DIRECT)
        spec = env.blueprint.spec
        self.obstacles = [
            p.createMultiBody(
                0,
                p.createCollisionShape(p.GEOM_BOX, halfExtents=list(o.half_extents), physicsClientId=self.client),
                basePosition=list(o.center),
                physicsClientId=self.client,
            )
            for o in scene_obstacles(spec)
        ]
        # the base turned by PyBullet's own reading of the rpy, not by envfactory's
        self.body = p.loadURDF(
            str(env.kinematics.urdf_path),
            basePosition=list(spec.robot.mount),
            baseOrientation=p.getQuaternionFromEuler(list(spec.robot.mount_rpy)),
            useFixedBase=True,
            physicsClientId=self.client,
        )
        infos = [
            p.getJointInfo(self.body, j, physicsClientId=self.client)
            for j in range(p.getNumJoints(self.body, physicsClientId=self.client))
        ]
        self.joint_index = {info[1].decode(): info[0] for info in infos}
        link_index = {info[12].decode(): info[0] for info in infos}
        link_index[p.getBodyInfo(self.body, physicsClientId=self.client)[0].decode()] = -1
        self.links = [i for i in range(-1, len(infos))]
        # the self pairs a user expects kept apart: every pair but those the check exempts by structure
        exempt = {frozenset(key) for key in env.safety.collision.ignored}
        shape_link = {shape.name: shape.link for shape in env.safety.collision.shapes}
        exempt_links = {frozenset(shape_link[name] for name in key) for key in exempt}
        collision_links = {link_index[shape.link] for shape in env.safety.collision.shapes}
        names = {v: k for k, v in link_index.items()}
        self.self_pairs = [
            (a, b)
            for a in sorted(collision_links)
            for b in sorted(collision_links)
            if a < b and frozenset((names[a], names[b])) not in exempt_links
        ]
        robot = spec.robot
        self.arm = [self.joint_index[j.name] for j in robot.arm_joints]
        self.gripper = None
        if robot.gripper is not None:
            self.gripper = [(self.joint_index[robot.gripper.joint], 1.0)] + [
                (self.joint_index[name], gain) for name, gain in robot.gripper.mimic.items()
            ]
        self.moving = [link_index[shape.link] for shape in env.safety.collision.shapes if shape.joint != 0]

    def close(self):
        p.disconnect(self.client)

    def _lowest(self, client, body, obstacles, self_pairs: bool = True) -> tuple[float, str]:
        lowest, what = np.inf, ""
        for link in set(self.moving):
            for obstacle in obstacles:
                for point in p.getClosestPoints(body, obstacle, self.margin, linkIndexA=link, physicsClientId=client):
                    if point[8] < lowest:
                        lowest, what = point[8], f"link {link} / body {obstacle}"
        for a, b in self.self_pairs if self_pairs else ():
            for point in p.getClosestPoints(
                body, body, self.margin, linkIndexA=a, linkIndexB=b, physicsClientId=client
            ):
                if point[8] < lowest:
                    lowest, what = point[8], f"links {a} / {b}"
        return lowest, what

    def lowest(self, joints: dict[str, float]) -> tuple[float, str]:
        """The lowest clearance from the obstacles (below the margin, else inf) in the judge's own client, the
        robot posed joint by joint by URDF name (a pose another engine simulated)."""
        for name, value in joints.items():
            if name in self.joint_index:
                p.resetJointState(self.body, self.joint_index[name], float(value), physicsClientId=self.client)
        p.performCollisionDetection(physicsClientId=self.client)
        return self._lowest(self.client, self.body, self.obstacles, self_pairs=False)

    def simulated(self) -> tuple[float, str]:
        """The lowest clearance in the simulated scene now (below the margin, else inf)."""
        return self._lowest(self.sim_client, self.sim_body, self.sim_obstacles)

    def pose(self, q_arm, gripper):
        for joint, value in zip(self.arm, q_arm):
            p.resetJointState(self.body, joint, float(value), physicsClientId=self.client)
        if self.gripper is not None:
            for joint, gain in self.gripper:
                p.resetJointState(self.body, joint, float(gain * gripper), physicsClientId=self.client)
        p.performCollisionDetection(physicsClientId=self.client)

    def commanded(self, q_from, q_to, gripper_from, gripper_to, samples: int = 24) -> tuple[float, str]:
        """The lowest clearance along the commanded motion, the gripper at both of its ends."""
        lowest, what = np.inf, ""
        for fraction in np.linspace(0.0, 1.0, samples + 1)[1:]:
            for gripper in {gripper_from, gripper_to}:
                self.pose(q_from + fraction * (q_to - q_from), gripper)
                value, where = self._lowest(self.client, self.body, self.obstacles)
                if value < lowest:
                    lowest, what = value, f"{where} at {fraction:.2f}"
        return lowest, what


# ---------------------------------------------------------------- policies


def _down(env, rng, step):
    """The end effector straight down at full scale (EE mode); in joint mode, shoulder and elbow driven
    to fold the arm onto the table."""
    low, high = env.action_space.low, env.action_space.high
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    if env.blueprint.action.ee:
        action[2] = low[2]
    else:
        action[1], action[2] = high[1], high[2]
    if env.blueprint.action.gripper_in_action:
        action[-1] = high[-1] if step % 2 else low[-1]
    return action


def _extremes(env, rng, step):
    low, high = env.action_space.low, env.action_space.high
    return np.where(rng.random(low.shape) < 0.5, low, high).astype(np.float32)


def _random(env, rng, step):
    return rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)


class _Repeated:
    """One random action, held for the whole episode."""

    def __init__(self):
        self.action = None

    def __call__(self, env, rng, step):
        if step == 0 or self.action is None:
            self.action = _random(env, rng, step)
        return self.action


POLICIES = {"random": lambda: _random, "down": lambda: _down, "extremes": lambda: _extremes, "repeated": _Repeated}
ADVERSARIAL = ("down", "extremes", "repeated")


JUDGED_COLUMNS = ["accepted", "refused", "inside margin", "lowest (m)"]


def judged_cells(result: dict) -> list:
    """A judged run's counts, in JUDGED_COLUMNS' order: what every safety page reports of it."""
    return [result["accepted"], result["rejected"], len(result["violations"]), f"{result['lowest']:.4f}"]


def drive_policy(env, policy_name: str, steps: int, seed: int, episode_length: int, on_accepted, before_step=None):
    """Run a policy for `steps` steps, a new episode every `episode_length` (or at its end); `before_step(state,
    command)` sees each command before it is stepped, `on_accepted(step, state, command)` each accepted one after.
    Returns (accepted, rejected)."""
    policy = POLICIES[policy_name]()
    rng = np.random.default_rng(seed)
    accepted = rejected = 0
    env.reset(seed=seed)
    step_in_episode = 0
    for step in range(steps):
        state = env.state
        action = policy(env, rng, step_in_episode)
        command = env.actions.translate(action, state)
        if before_step is not None:
            before_step(state, command)
        _, _, terminated, truncated, info = env.step(action)
        step_in_episode += 1
        if info["action_rejected"]:
            rejected += 1
        else:
            accepted += 1
            on_accepted(step, state, command)
        if terminated or truncated or step_in_episode >= episode_length:
            env.reset()
            step_in_episode = 0
    return accepted, rejected


def judge_steps(env, policy_name: str, steps: int, seed: int = 0, episode_length: int = 25) -> dict:
    """Run a policy and judge every accepted step with Bullet: after the step in the simulated scene,
    and along the commanded motion. Counts, and the worst case seen."""
    margin = env.blueprint.spec.env.safety.surface_margin
    judge = BulletJudge(env, margin)
    result = {"violations": [], "lowest": np.inf}

    def judged(step, state, command) -> None:
        gripper_to = state.gripper if command.gripper is None else command.gripper
        for where, (value, what) in (
            ("simulated", judge.simulated()),
            ("commanded", judge.commanded(state.q_arm, command.q_arm, state.gripper, gripper_to)),
        ):
            result["lowest"] = min(result["lowest"], value)
            if value < margin:
                result["violations"].append((step, where, round(float(value), 4), what))

    try:
        result["accepted"], result["rejected"] = drive_policy(env, policy_name, steps, seed, episode_length, judged)
    finally:
        judge.close()
    return result
