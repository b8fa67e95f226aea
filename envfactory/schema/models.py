"""The validated shape of a composed env spec: robot x task, the env settings,
the scene, and the IDs it registers. Each part lives in its own module; this
one joins them and re-exports every model under one name."""

from __future__ import annotations

from pydantic import Field, model_validator

from envfactory.schema.base import Model, Position, Rpy, Vec3, located
from envfactory.schema.numbers import NonNegative, Positive, Real
from envfactory.schema.robot import (
    DEFAULT_JOINT_DELTA,
    ArmJoint,
    ContactSpec,
    FrameSpec,
    GripperSpec,
    JointStateEntry,
    ModelSpec,
    PedestalSpec,
    RobotSafety,
    RobotSpec,
    UrdfPart,
)
from envfactory.schema.ros import ArmCommand, GripperCommand, RosSpec, RosTopic, StaticTransform
from envfactory.schema.settings import (
    ActionSettings,
    CameraSpec,
    EnvSettings,
    IdEntry,
    ObstacleSpec,
    RealSettings,
    Registration,
    SafetySettings,
    SceneSpec,
    SimSettings,
    TableSpec,
    TimingSettings,
    Workspace,
)
from envfactory.schema.task import (
    ExpertRef,
    FixtureSpec,
    GoalSpec,
    GripperUse,
    LiftSpec,
    ObjectSpec,
    RewardSets,
    SpawnSpec,
    TaskSpec,
    TerminationRef,
    TermRef,
)


class ComposedSpec(Model):
    """A composed env family: robot x task, plus the IDs it registers."""

    robot: RobotSpec
    task: TaskSpec
    env: EnvSettings = EnvSettings()
    scene: SceneSpec
    sim: SimSettings = SimSettings()
    workspace: Workspace
    registration: Registration
    kwargs: dict[str, str] = {}
    # Python modules to import before the terms are resolved: a user's own terms.
    terms: list[str] = Field(default=[], max_length=50)

    @model_validator(mode="after")
    def _gripper_needed(self) -> "ComposedSpec":
        uses_gripper = self.task.gripper.in_action or self.task.gripper.at_reset != "unchanged"
        if uses_gripper and self.robot.gripper is None:
            # placed at the robot: the robot was chosen without one, the task is as it should be
            use = "in its action" if self.task.gripper.in_action else f"at reset ({self.task.gripper.at_reset})"
            raise located(
                "robot.gripper",
                f"task {self.task.name!r} drives a gripper ({use}, task.gripper) but robot "
                f"{self.robot.name!r} declares none: choose a robot with a gripper, add a "
                f"'gripper:' block to the robot's YAML, or use a task without one",
            )
        at_reset = self.task.gripper.at_reset
        if isinstance(at_reset, float) and not self.robot.gripper.low <= at_reset <= self.robot.gripper.high:
            raise located(
                "task.gripper.at_reset",
                f"task.gripper.at_reset {at_reset} lies outside the gripper's range "
                f"[{self.robot.gripper.low}, {self.robot.gripper.high}]",
            )
        return self

    @property
    def gripper_at_reset(self) -> float | None:
        """The gripper joint value a reset commands, or None to leave it as it is."""
        at_reset, gripper = self.task.gripper.at_reset, self.robot.gripper
        if at_reset == "unchanged" or gripper is None:
            return None
        return {"open": gripper.open, "closed": gripper.closed}.get(at_reset, at_reset)

    @property
    def gripper_assumed_at_reset(self) -> float:
        """The gripper value the first motion after a reset starts from: the commanded one, else open (a
        gripper left as it is may be anywhere; open is the widest the proof must clear), 0 without one."""
        if self.gripper_at_reset is not None:
            return self.gripper_at_reset
        return self.robot.gripper.open if self.robot.gripper is not None else 0.0


__all__ = [
    "DEFAULT_JOINT_DELTA",
    "ActionSettings",
    "ArmCommand",
    "ArmJoint",
    "CameraSpec",
    "ContactSpec",
    "EnvSettings",
    "ComposedSpec",
    "ExpertRef",
    "FrameSpec",
    "GoalSpec",
    "GripperCommand",
    "GripperSpec",
    "FixtureSpec",
    "GripperUse",
    "IdEntry",
    "JointStateEntry",
    "LiftSpec",
    "Model",
    "ModelSpec",
    "Position",
    "Rpy",
    "NonNegative",
    "ObjectSpec",
    "ObstacleSpec",
    "PedestalSpec",
    "Positive",
    "Real",
    "RealSettings",
    "Registration",
    "RewardSets",
    "RobotSpec",
    "RosSpec",
    "RosTopic",
    "RobotSafety",
    "SafetySettings",
    "SceneSpec",
    "SimSettings",
    "SpawnSpec",
    "StaticTransform",
    "TableSpec",
    "TaskSpec",
    "TermRef",
    "TerminationRef",
    "TimingSettings",
    "UrdfPart",
    "Vec3",
    "Workspace",
]
