"""Whether the fingers hold a fixture's touchable part (a drawer's handle), and the motions a held part allows.

A drawer's handle moves with the fingers that hold it, but only along the drawer's travel. The safety check
measures the fixture where its joint stands now, so the fingers pulling the handle are commanded into its
present place by a whole step: while they hold it, their pairs with it keep no margin (safety.HELD_MARGIN), and
this guard refuses instead any motion that would take the hand across the travel, where the handle cannot
follow and the arm would strain against the cabinet. Fingers commanded shut but not yet on it may be commanded
the fixture's touch depth into it: enough to close on it. An open hand may touch it and no more: pressed on it,
its fingers would be forced open past their stops (measured: the UR5e knuckle 12 mrad past its stop with the
touch depth allowed to an open hand).
"""

from __future__ import annotations

import numpy as np

from envfactory.geometry.judged_motion import ACCEPTED, Verdict


class FixtureHold:
    # a finger this near a touchable box is on it (engines disagree on contact by about a millimetre)
    CONTACT = 0.003
    # the gripper commanded at least this far closed (of its range) holds what its fingers are on; a hand open
    # less is resting on it. The command, not the reading: a held handle that runs on can push the jaws open.
    CLOSED = 0.75
    # m of EE travel across the joint's line a held part takes: its joint's play, not a strain
    ACROSS = 0.01

    def __init__(self, safety, fixtures: dict, task_frame, gripper):
        self.safety, self.collision, self.kinematics = safety, safety.collision, safety.kinematics
        self.gripper = gripper
        # each fixture's travel in the task frame (the EE's frame)
        self.travel = {
            name: task_frame.rotation.T @ fixture.travel
            for name, fixture in fixtures.items()
            if name in self.collision.touch_pairs
        }
        self.held: dict[str, bool] = {name: False for name in self.travel}
        self._commanded: float | None = None  # the gripper's last command

    def reset(self, gripper: float | None) -> None:
        """An episode starts with the gripper at `gripper` (None: as it was) and nothing held."""
        self._commanded = gripper if gripper is not None else self._commanded
        self.held = {name: False for name in self.travel}

    def _shut(self, command: float) -> bool:
        return self.gripper is not None and self.gripper.closure(command) >= self.CLOSED

    def sent(self, gripper: float) -> None:
        """The gripper was commanded to `gripper` (an accepted step's command)."""
        self._commanded = gripper

    def judge(self, state, q_target: np.ndarray, gripper_target: float | None) -> Verdict:
        """Whether each fixture's touchable part is held as this step starts (the safety check's margins follow),
        and whether the commanded motion keeps a held part to its travel."""
        last = state.gripper if self._commanded is None else self._commanded
        closed = self._shut(last)  # as the step starts
        closing = closed or (gripper_target is not None and self._shut(gripper_target))
        for name in self.travel:
            held = False
            if closed:
                self.collision.pose(state.q_arm, state.gripper)
                held = bool(self.collision.exact(self.collision.touch_pairs[name]).min() <= self.CONTACT)
            self.held[name] = held
            self.safety.touch_fixture(name, "held" if held else "closing" if closing else "open")
        for name, held in self.held.items():
            if not held:
                continue
            gripper = state.gripper if gripper_target is None else gripper_target
            ee_to = self.kinematics.ee_pose(np.asarray(q_target, float), gripper)[0]
            move = ee_to - state.ee_position
            travel = self.travel[name]
            across = float(np.linalg.norm(move - (move @ travel) * travel))
            if across > self.ACROSS:
                return Verdict(
                    False,
                    f"the fingers hold {name}'s touchable part, which moves only along its joint: this motion takes "
                    f"the hand {across:.3f} m across it (at most {self.ACROSS} m)",
                )
        return ACCEPTED
