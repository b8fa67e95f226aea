"""Measures `sim.fidelity: fast` against full dynamics, the reference.

Two measures, both on ordinary episodes of an env made with the fast fidelity:

- paired steps: before every cycle the PyBullet state is saved, the cycle is
  simulated in full (every substep), the scene read, the state restored, and
  the same cycle played fast. Both start from the identical state, so the gap
  is the fast player's own error in one step, free of the divergence of two
  trajectories (a closed-loop expert amplifies any gap into different actions).
  The episode goes on from the fast outcome, as a fast env would.
- trajectories: a fast and a full env from the same seed, fed the same actions;
  the gap at the end of every step, accumulated over the episode. A strike that
  tumbles an object is chaotic: full dynamics does not reproduce it against
  itself either. So the trajectory's bar is the tolerance or, where larger, the
  spread of full dynamics over the same actions with the objects nudged 1 µm at
  reset (full_spread): the fast player is not asked to be more repeatable than
  the reference is.

Used by tests/test_fidelity.py and devkit/bench/fidelity.py.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import gymnasium as gym
import mujoco
import numpy as np
import pybullet as p

from envfactory.experts import make_policy
from envfactory.geometry.kinematics import quaternion_to_matrix

# the tolerances of the fast fidelity against full dynamics (design.md, budgets)
EE_TOLERANCE = 1e-3
OBJECT_TOLERANCE = 2e-3
ANGLE_TOLERANCE = np.radians(2.0)


@dataclass
class SceneReading:
    q_arm: np.ndarray
    gripper: float
    ee: np.ndarray
    objects: dict[str, tuple[np.ndarray, np.ndarray]]  # name -> (position, rotation matrix)


@dataclass
class Gaps:
    """Per step: EE (m), largest arm joint (rad), gripper (its unit), object position (m) and angle (rad);
    and how the fast player played each paired cycle."""

    ee: list[float] = field(default_factory=list)
    joint: list[float] = field(default_factory=list)
    gripper: list[float] = field(default_factory=list)
    object_position: list[float] = field(default_factory=list)
    object_angle: list[float] = field(default_factory=list)
    kinds: list[str] = field(default_factory=list)

    def add(self, fast: SceneReading, full: SceneReading) -> None:
        self.ee.append(float(np.linalg.norm(fast.ee - full.ee)))
        self.joint.append(float(np.abs(fast.q_arm - full.q_arm).max()))
        self.gripper.append(abs(fast.gripper - full.gripper))
        for name, (position, rotation) in fast.objects.items():
            other_position, other_rotation = full.objects[name]
            self.object_position.append(float(np.linalg.norm(position - other_position)))
            self.object_angle.append(rotation_angle(rotation, other_rotation))

    def extend(self, other: "Gaps") -> None:
        for name in ("ee", "joint", "gripper", "object_position", "object_angle", "kinds"):
            getattr(self, name).extend(getattr(other, name))


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle of the rotation taking a to b."""
    cosine = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.arccos(np.clip(cosine, -1.0, 1.0)))


def read_scene(env) -> SceneReading:
    """The scene as the backend holds it now, through the env's own readers."""
    u = env.unwrapped
    reading = u.backend.read_joints()
    q_arm = reading.position[u._arm_in_states]
    gripper = float(reading.position[u._gripper_in_states]) if u._gripper_in_states is not None else 0.0
    ee, _ = u.kinematics.ee_pose(q_arm, gripper)
    objects = {}
    task = u.blueprint.spec.task
    for name in (*task.objects, *task.fixtures):  # spawned by every reset, or standing (a drawer's handle)
        obj = u.backend.read_object(name)
        objects[name] = (obj.position.copy(), quaternion_to_matrix(obj.quaternion))
    return SceneReading(q_arm.copy(), gripper, ee.copy(), objects)


class _BulletSnapshot:
    """PyBullet's whole state, and the switch between its fast player and full dynamics."""

    def __init__(self, backend):
        if getattr(backend, "_fast", None) is None:
            raise ValueError("PairedSteps needs an env made with sim.fidelity fast")
        self.backend, self.fast = backend, backend._fast

    def save(self):
        return self.backend.save_state()

    def restore(self, saved) -> None:
        self.backend.restore_state(saved)
        self.backend.drop_state(saved)

    def play_full(self, advance, seconds: float) -> None:
        # the fast player programs the arm's motors when a cycle first steps the physics: the reference,
        # which steps every cycle, gives them the command first (restore gives the fast one it back)
        self.backend.program_pending_arm()
        self.backend._fast = None
        try:
            advance(seconds)
        finally:
            self.backend._fast = self.fast


class _MujocoSnapshot:
    """MuJoCo's whole physics state with the backend's own (controls, clock, grasp record), and the switch."""

    def __init__(self, backend):
        import mujoco

        if not backend.cycles.fast:
            raise ValueError("PairedSteps needs an env made with sim.fidelity fast")
        self.backend, self.cycles, self.mujoco = backend, backend.cycles, mujoco
        self.kind = mujoco.mjtState.mjSTATE_FULLPHYSICS

    def save(self):
        backend, mujoco = self.backend, self.mujoco
        state = np.zeros(mujoco.mj_stateSize(backend.model, self.kind))
        mujoco.mj_getState(backend.model, backend.data, state, self.kind)
        cycles = self.cycles
        carry = None if cycles._carry is None else copy.deepcopy(cycles._carry.__dict__)
        return state, backend.data.ctrl.copy(), cycles.sim_time, cycles._settled, carry, copy.copy(cycles.counts)

    def restore(self, saved) -> None:
        backend, cycles = self.backend, self.cycles
        state, backend.data.ctrl[:], cycles.sim_time, cycles._settled, carry, cycles.counts = saved
        self.mujoco.mj_setState(backend.model, backend.data, state, self.kind)
        if carry is not None:
            cycles._carry.__dict__.update(carry)
        self.mujoco.mj_forward(backend.model, backend.data)

    def play_full(self, advance, seconds: float) -> None:
        self.cycles.fast = False
        try:
            advance(seconds)
        finally:
            self.cycles.fast = True


class PairedSteps:
    """Wraps a fast env's backend so that every cycle is also simulated in full from the same state."""

    KINDS = ("kinematic", "at_rest", "carried", "dynamic")

    def __init__(self, env):
        self.env = env
        self.backend = env.unwrapped.backend
        self.snapshot = (_MujocoSnapshot if hasattr(self.backend, "model") else _BulletSnapshot)(self.backend)
        self.gaps = Gaps()
        self._advance = self.backend.advance
        self.backend.advance = self._paired_advance

    def _paired_advance(self, seconds: float) -> None:
        saved = self.snapshot.save()
        self.snapshot.play_full(self._advance, seconds)  # the reference: every substep
        full = read_scene(self.env)
        self.snapshot.restore(saved)
        counts = self.backend.cycle_counts
        before = [getattr(counts, kind) for kind in self.KINDS]
        self._advance(seconds)
        self.gaps.add(read_scene(self.env), full)
        after = [getattr(self.backend.cycle_counts, kind) for kind in self.KINDS]
        self.gaps.kinds.append(self.KINDS[int(np.argmax(np.subtract(after, before)))])

    def close(self) -> None:
        self.backend.advance = self._advance


def policy_for(env, kind: str, seed: int):
    policy = make_policy(kind, env, seed=seed)
    return policy


def paired_episode(env_id: str, policy: str, seed: int, steps: int | None = None, **kwargs) -> tuple[Gaps, bool]:
    """One episode of a fast env with every cycle paired against full dynamics; and the expert's success."""
    env = gym.make(env_id, physics_fidelity="fast", **kwargs)
    try:
        pairs = PairedSteps(env)
        observation, _ = env.reset(seed=seed)
        actor = policy_for(env, policy, seed)
        success = False
        for _ in range(steps or env.spec.max_episode_steps):
            observation, _, terminated, truncated, info = env.step(actor(observation))
            success = success or bool(info["is_success"])  # the whole episode is measured, success or not
            if terminated or truncated:
                break
        pairs.close()
        return pairs.gaps, success
    finally:
        env.close()


def _same_actions(envs, seed: int, steps: int) -> Gaps:
    """Two envs (reset already) fed the same random actions from `seed`: the gap of the first from the second at
    the end of every step, until either episode ends."""
    envs[0].action_space.seed(seed)
    gaps = Gaps()
    for _ in range(steps):
        action = envs[0].action_space.sample()
        ends = [env.step(action)[2:4] for env in envs]
        gaps.add(read_scene(envs[0]), read_scene(envs[1]))
        if any(terminated or truncated for terminated, truncated in ends):
            break
    return gaps


def trajectory_gaps(env_id: str, seed: int, steps: int, **kwargs) -> Gaps:
    """A fast and a full env from one seed, fed the same random actions."""
    envs = [gym.make(env_id, physics_fidelity=fidelity, **kwargs) for fidelity in ("fast", "full")]
    try:
        for env in envs:
            env.reset(seed=seed)
        return _same_actions(envs, seed, steps)
    finally:
        for env in envs:
            env.close()


NUDGE = 1e-6  # m: how far full_spread moves each free object at reset


def _nudge(env, distance: float) -> None:
    """Move every free object `distance` along x in the engine, at rest: a difference far below any sensor's."""
    u = env.unwrapped
    backend = u.backend
    for name in u.blueprint.spec.task.objects:
        if hasattr(backend, "model"):  # MuJoCo
            address = backend.handles.object_qpos[name]
            backend.data.qpos[address] += distance
            mujoco.mj_forward(backend.model, backend.data)
        else:
            body, client = backend.objects[name], backend.client
            position, orientation = p.getBasePositionAndOrientation(body, physicsClientId=client)
            moved = [position[0] + distance, position[1], position[2]]
            p.resetBasePositionAndOrientation(body, moved, orientation, physicsClientId=client)


def full_spread(env_id: str, seed: int, steps: int, **kwargs) -> Gaps:
    """Full dynamics against itself: two full envs from one seed, fed trajectory_gaps' actions, the first's
    objects nudged NUDGE at reset. How far the reference itself strays where the episode is chaotic."""
    envs = [gym.make(env_id, physics_fidelity="full", **kwargs) for _ in range(2)]
    try:
        for env in envs:
            env.reset(seed=seed)
        _nudge(envs[0], NUDGE)
        return _same_actions(envs, seed, steps)
    finally:
        for env in envs:
            env.close()


def expert_success(env_id: str, fidelity: str, seeds, **kwargs) -> list[bool]:
    """The scripted expert's success per seed, with the given fidelity: the goal reached at some step."""
    env = gym.make(env_id, physics_fidelity=fidelity, **kwargs)
    try:
        out = []
        for seed in seeds:
            observation, _ = env.reset(seed=seed)
            actor = policy_for(env, "scripted", seed)
            success = False
            for _ in range(env.spec.max_episode_steps):
                observation, _, terminated, truncated, info = env.step(actor(observation))
                success = bool(info["is_success"])
                # success is the goal reached, as the episode runner counts it: what a PnP expert does
                # after placing the cube (open, leave) is not its task
                if success or terminated or truncated:
                    break
            out.append(success)
        return out
    finally:
        env.close()


def assert_within(gaps, what: str, spread: Gaps | None = None) -> None:
    """Every gap within its tolerance, or within full dynamics' own spread (full_spread) where that is larger."""

    def bar(tolerance: float, name: str) -> float:
        own = getattr(spread, name) if spread is not None else []
        return max(tolerance, max(own, default=0.0))

    assert gaps.ee, f"{what}: no step was measured"
    ee = bar(EE_TOLERANCE, "ee")
    assert max(gaps.ee) <= ee, f"{what}: EE {1e3 * max(gaps.ee):.3f} mm from full dynamics (bar {1e3 * ee:.3f})"
    if gaps.object_position:
        position, angle = bar(OBJECT_TOLERANCE, "object_position"), bar(ANGLE_TOLERANCE, "object_angle")
        assert max(gaps.object_position) <= position, (
            f"{what}: object {1e3 * max(gaps.object_position):.3f} mm from full dynamics (bar {1e3 * position:.3f})"
        )
        assert max(gaps.object_angle) <= angle, (
            f"{what}: object turned {np.degrees(max(gaps.object_angle)):.3f}° from full dynamics "
            f"(bar {np.degrees(angle):.3f}°)"
        )
