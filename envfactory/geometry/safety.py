"""Decides whether a joint target may be sent to the arm.

One check serves sim and real: finite values, joint bounds, the largest joint change allowed in one action, and the
clearance of every link's collision shapes from the scene's obstacles and from the arm's other links, proven over
the whole commanded motion (the gripper's included), not sampled: two safe end poses can sweep a link through the
table between any two samples.

The proof rests on one bound. A joint change Δq moves no point of a shape farther than lever · |Δq| (its
per-coordinate lever arms), so clearances known at two poses of a straight joint-space motion bound the clearance
everywhere between them: at least (c_a + c_b - travel) / 2. Pieces whose bound falls short are halved until they are
proven, found unsafe, or too small to split: then the motion is refused. A doubt stops the arm.
"""

from __future__ import annotations

import math

import numpy as np

from envfactory.geometry.collision import CollisionModel
from envfactory.geometry.judged_motion import ACCEPTED, Anchor, Motion, Verdict, weak_pairs
from envfactory.geometry.kernels.outcomes import DOUBT_AT_ENDS, PROVEN
from envfactory.schema.models import SafetySettings

# The margin a held touchable part keeps from the fingers (a drawer's handle they pull): none, however deep the
# commanded motion takes them into where it stands now, since it moves with them (a finite number: the proofs'
# arithmetic never meets an infinity). fixture_hold.py allows such motions only along the part's travel.
HELD_MARGIN = -1.0


class SafetyCheck:
    """One env's safety check of every command (sim and real): joint bounds, the largest joint change, and the
    clearance over the whole motion, with its own measuring copy of the shared CollisionModel (one per env)."""

    # Bisection stops at pieces this small. Deep pieces are needed only where a pair starts
    # inside the margin and must prove it does not get closer.
    FINEST_PIECE = 1.0 / 512
    # A pair that starts inside the margin may dip this much below where it started on its
    # way out: the bisection cannot prove an exact non-decrease.
    INSIDE_TOLERANCE = 0.002
    # A remembered end pose stands in for the next start if the arm ended this close to it.
    REUSE_WITHIN = 0.003
    # Kept in hand beyond the margin, per robot shape in a pair: engines disagree on the same URDF
    # (PyBullet pads each shape with a collision margin that coal does not): measured 1.0 mm for a
    # link against an obstacle, 2.0 mm for two meshed links.
    SHAPE_TOLERANCE = 0.001
    ROUNDING = 0.0002
    # Pieces left with at most this many unproven pairs measure them with coal alone.
    FEW_PAIRS = 12
    # Halvings of a motion on capsule bounds alone before coal measures what they leave (8 pieces: 7 poses)
    CAPSULE_LEVELS = 3
    # Further halvings of the pieces a pair still leaves, on capsule bounds and that pair alone, before coal
    DEEPER_LEVELS = 3
    # Gripper values sampled first across the gripper's range (as shares of it), before finer sweeps where needed.
    COARSE_FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)
    # Gripper values are sampled this finely (in clearance lost between samples) when its motion matters.
    SWEEP_RESOLUTION = 0.001

    def __init__(self, collision: CollisionModel, settings: SafetySettings):
        self.collision = collision
        self.kinematics = collision.kinematics
        self.settings = settings
        scene, own = len(collision.scene_shape), len(collision.self_a)
        tolerance = self.ROUNDING + self.SHAPE_TOLERANCE * np.repeat([1.0, 2.0], [scene, own])
        # A self pair the robot's design holds inside the surface margin keeps the margin the generated pair
        # list gives it instead (down to zero: contact): the surface margin would refuse the poses the arm is
        # built to take, and skipping the pair would let a motion fold those links into each other.
        # (fmin passes over NaN, which marks the pairs that keep the surface margin)
        self.margin = np.fmin(collision.pair_margin, settings.surface_margin) + tolerance
        self._closing_margin = self.margin.copy()  # a touchable part's pairs while the gripper closes on it
        # the last accepted motion's end pose and the gripper range it was judged over
        self._last_end: tuple[Anchor, tuple[float, float]] | None = None

    # ------------------------------------------------------------ single poses

    def clearances(self, q_arm: np.ndarray, gripper: float = 0.0) -> np.ndarray:
        """Exact clearance of every measured pair at one pose."""
        self.collision.pose(np.asarray(q_arm, float), gripper)
        return self.collision.all_exact()

    def pose_is_clear(self, q_arm: np.ndarray, gripper: float = 0.0) -> bool:
        return self._pose_verdict(np.asarray(q_arm, float), gripper).accepted

    def _pose_verdict(self, q_arm: np.ndarray, gripper: float, where: str = "") -> Verdict:
        count = self.collision.pair_count
        still = Motion(q_arm, q_arm, gripper, gripper, np.zeros(count), np.zeros(count), self.margin.copy())
        return self._settle(self._anchor(1.0, still), still, where)

    # ------------------------------------------------------------ motions

    def check(
        self,
        q_arm_now: np.ndarray,
        q_arm_target: np.ndarray,
        gripper_now: float = 0.0,
        gripper_target: float | None = None,
    ) -> Verdict:
        """Whether the arm may move from now to the target (and the gripper to its target, if given)."""
        q_arm_target = np.asarray(q_arm_target, float)
        if not np.isfinite(q_arm_target).all():
            return Verdict(False, "non-finite joint target")
        kin = self.kinematics
        if ((q_arm_target < kin.arm_lower) | (q_arm_target > kin.arm_upper)).any():
            return Verdict(False, "joint target outside the joint bounds")
        delta = q_arm_target - q_arm_now
        largest = float(np.abs(delta).max())
        # (the target is finite: a NaN or infinite change comes from the reading; every bound would be NaN, and
        # a NaN compares false with every threshold, so it would pass for clear)
        if not (math.isfinite(largest) and math.isfinite(gripper_now)):
            return Verdict(False, "non-finite joint reading: where the arm is now is unknown")
        if largest > self.settings.max_joint_delta + 1e-12:
            return Verdict(
                False, f"joint change {largest:.3f} rad exceeds max_joint_delta {self.settings.max_joint_delta}"
            )
        if gripper_target is not None and not np.isfinite(gripper_target):
            return Verdict(False, "non-finite gripper target")
        return self._motion_verdict(
            np.asarray(q_arm_now, float),
            q_arm_target,
            gripper_now,
            gripper_now if gripper_target is None else float(gripper_target),
            self.FINEST_PIECE,
            remember=True,
        )

    def path_is_clear(
        self, q_from: np.ndarray, q_to: np.ndarray, gripper_from: float = 0.0, gripper_to: float | None = None
    ) -> Verdict:
        """Clearance along a long joint-space move (a real arm driving home), with no joint-change limit."""
        gripper_to = gripper_from if gripper_to is None else gripper_to
        q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
        if not (
            np.isfinite(q_from).all()
            and np.isfinite(q_to).all()
            and math.isfinite(gripper_from)
            and math.isfinite(gripper_to)
        ):
            return Verdict(False, "non-finite joint reading or target")
        return self._motion_verdict(q_from, q_to, gripper_from, gripper_to, self.FINEST_PIECE / 8, remember=False)

    def forget(self) -> None:
        """The arm moved without a check (a reset): the remembered end pose no longer applies."""
        self._last_end = None

    def touch_fixture(self, name: str, grip: str) -> None:
        """How the fingers meet fixture `name`'s touchable part (fixture_hold.py), and the margin their pairs with it
        keep: `held` (closed on it: it moves with them along its joint) none at all (HELD_MARGIN); `closing` (the
        gripper commanded shut) the fixture's touch depth into it, enough to close on it; `open` none into it, as
        far as touching it, so that an open hand never forces its fingers apart on it. A remembered end pose
        measured under other margins no longer applies."""
        pairs = self.collision.touch_pairs.get(name)
        if pairs is None:
            return
        if grip == "held":
            wanted = np.full(len(pairs), HELD_MARGIN)
        elif grip == "closing":
            wanted = self._closing_margin[pairs]
        else:
            wanted = self._closing_margin[pairs] - self.collision.pair_margin[pairs]  # the margin 0 + tolerance
        if not np.array_equal(self.margin[pairs], wanted):
            self.margin[pairs] = wanted
            self._last_end = None

    def place_fixture(self, name: str, opening: float) -> None:
        """A fixture's joint reads `opening` past its lower limit: its moving boxes go there, and a remembered end
        pose, measured against them where they were, no longer applies."""
        if self.collision.move_fixture(name, opening):
            self._last_end = None

    def _motion_verdict(self, q_from, q_to, gripper_from, gripper_to, finest, remember) -> Verdict:
        collision = self.collision
        # The gripper moves on its own clock: any of its values between start and target may meet
        # any arm pose, so each pose is judged over the gripper's whole range.
        gripper_range = tuple(sorted((gripper_from, gripper_to)))
        # Most motions the capsule bounds prove alone (at the two ends, then at a few evenly spaced poses between
        # them, in one compiled pass: far cheaper than coal at the ends). Only where they leave a pair in doubt
        # does the rest of this run, on what that pass measured.
        way = q_to - q_from
        proof = collision.motion_proof(
            q_from,
            way,
            gripper_from,
            gripper_to,
            self.margin,
            self._reusable_end(gripper_range),
            self.REUSE_WITHIN,
            self.CAPSULE_LEVELS,
            self.DEEPER_LEVELS,
        )
        # (the end pose as Motion.arm_at(1.0) gives it)
        end = Anchor(1.0, q_from + way, proof.end_bound, np.zeros(collision.pair_count, dtype=np.int8))
        if proof.outcome == PROVEN:
            if remember:
                self._last_end = (end, gripper_range)
            return ACCEPTED
        motion = Motion(
            q_from,
            q_to,
            gripper_from,
            gripper_to,
            proof.travel,
            proof.reserve,
            self.margin.copy(),
            proof.gripper_moves,
            collision.gripper_sweep.bracket(gripper_from, gripper_to) if proof.gripper_moves else (0, -1),
        )
        start = Anchor(0.0, q_from, proof.start_bound, np.zeros(collision.pair_count, dtype=np.int8))
        weak = proof.unproven
        if proof.outcome == DOUBT_AT_ENDS:
            verdict, weak = self._ends_in_doubt(start, end, motion)
            if not verdict.accepted:
                return verdict
        # A piece carries only the pairs its parent could not prove: a pair proven over a piece is
        # proven over every part of it, so deep pieces measure a handful of pairs, not all of them.
        pieces = [(start, end, weak)]
        while pieces:
            a, b, pairs = pieces.pop()
            length = b.fraction - a.fraction
            short = weak_pairs(a, b, motion, length, pairs)
            for level in (1, 2) if motion.gripper_moves else (1,):
                if short.size == 0:
                    break
                self._refine(a, short, motion, level)
                self._refine(b, short, motion, level)
                short = weak_pairs(a, b, motion, length, short)
            if short.size == 0:
                continue
            if short.size <= self.FEW_PAIRS:
                for pair in short:
                    verdict = self._prove_pair(
                        int(pair), a.fraction, a.bound[pair], b.fraction, b.bound[pair], motion, finest
                    )
                    if not verdict.accepted:
                        return verdict
                continue
            if length <= finest:
                return self._unproven(short[0], a.fraction)
            middle = self._anchor((a.fraction + b.fraction) / 2, motion, short)
            verdict = self._settle(middle, motion, f" at {middle.fraction:.0%} of the motion", short)
            if not verdict.accepted:
                return verdict
            pieces += [(a, middle, short), (middle, b, short)]
        if remember:
            self._last_end = (end, gripper_range)
        return ACCEPTED

    def _ends_in_doubt(self, start: Anchor, end: Anchor, motion: Motion) -> tuple[Verdict, np.ndarray]:
        """Coal settles the pairs the capsules leave below their margin at the motion's start or end; the verdict
        there, and the pairs still unproven between the two ends after the compiled pass."""
        collision = self.collision
        # a pair already inside the margin now (contact, tracking error) may only move out
        candidates = (start.bound < self.margin).nonzero()[0]
        now = np.zeros(0)
        if candidates.size:
            collision.pose(motion.q_from, motion.gripper_from)
            now = collision.exact(candidates)
        close = now < self.margin[candidates]
        inside, now = candidates[close], now[close]
        motion.threshold[inside] = np.minimum(now - self.INSIDE_TOLERANCE, self.margin[inside])
        verdict = self._settle(end, motion, " at the end of the motion")
        if verdict.accepted and inside.size:
            self._refine(end, inside, motion, level=2)
            stuck = inside[end.bound[inside] <= now]
            if stuck.size:
                verdict = Verdict(
                    False, self._describe(stuck[0], end.bound[stuck[0]], " and the motion does not move it away")
                )
        if not verdict.accepted:
            return verdict, inside[:0]
        weak = weak_pairs(start, end, motion, 1.0, None)
        if weak.size:
            weak = collision.unproven_by_capsules(
                motion.q_from,
                motion.way,
                motion.gripper_middle,
                weak,
                start.bound,
                end.bound,
                motion.travel,
                motion.reserve,
                motion.threshold,
                self.CAPSULE_LEVELS,
                self.DEEPER_LEVELS,
            )
        return ACCEPTED, weak

    def _prove_pair(
        self,
        pair: int,
        start: float,
        start_clearance: float,
        end: float,
        end_clearance: float,
        motion: Motion,
        finest: float,
    ) -> Verdict:
        """The bisection for one pair between two measured poses, on plain floats: the deep pieces
        near a pair that sits close to its threshold are many, and each costs one coal query."""
        travel, threshold = float(motion.travel[pair]), float(motion.threshold[pair])
        # the fingers' table is looser than coal by a few millimetres: a smallest piece it leaves unproven has its
        # two ends measured again with coal alone before the motion is refused. (Where coal's bounds prove a piece,
        # they prove each part of it, so this refuses exactly the motions a bisection on coal alone would refuse.)
        coal_alone: dict[float, float] = {}
        tabulated = motion.gripper_moves and self.collision.gripper_sweep.sweepable_one(pair)
        pieces = [(start, start_clearance, end, end_clearance)]
        while pieces:
            a, clearance_a, b, clearance_b = pieces.pop()
            if clearance_a + clearance_b - travel * (b - a) >= 2 * threshold:
                continue
            if b - a <= finest:
                if tabulated:
                    for f in (a, b):
                        if f not in coal_alone:
                            coal_alone[f] = self._pair_clearance(pair, motion.arm_at(f), motion, tabulated=False)
                    clearance_a, clearance_b = max(clearance_a, coal_alone[a]), max(clearance_b, coal_alone[b])
                    if clearance_a + clearance_b - travel * (b - a) >= 2 * threshold:
                        continue
                return self._unproven(pair, a)
            middle = (a + b) / 2
            clearance = self._pair_clearance(pair, motion.arm_at(middle), motion)
            if clearance < threshold:
                return Verdict(False, self._describe(pair, clearance, f" at {middle:.0%} of the motion"))
            pieces += [(a, clearance_a, middle, clearance), (middle, clearance, b, clearance_b)]
        return ACCEPTED

    def _pair_clearance(self, pair: int, q_arm: np.ndarray, motion: Motion, tabulated: bool = True) -> float:
        """A lower bound on one pair's clearance at an arm pose, over the gripper's range (the fingers'
        table first, unless told to measure with coal alone)."""
        collision = self.collision
        if not motion.gripper_moves or motion.reserve[pair] == 0.0:  # the gripper cannot change it
            collision.pose(q_arm, motion.gripper_middle)
            return collision.exact_one(pair)
        if tabulated and collision.gripper_sweep.sweepable_one(pair):
            collision.pose(q_arm, motion.gripper_middle)
            clearance = collision.gripper_sweep.clearance_one(pair, *motion.samples)
            if clearance >= motion.threshold[pair]:
                return clearance
        # coal across the gripper's range (the table, where it applies, fell short above)
        coarse = [
            self._pose_with_gripper(q_arm, motion, fraction).exact_one(pair) for fraction in self.COARSE_FRACTIONS
        ]
        return self._gripper_range_bound(q_arm, motion, pair, coarse)

    def _unproven(self, pair: int, fraction: float) -> Verdict:
        names = " and ".join(self.collision.pair_names(pair))
        return Verdict(False, f"cannot prove {names} stay clear near {fraction:.0%} of the motion")

    # ------------------------------------------------------------ anchors

    def _anchor(self, fraction: float, motion: Motion, pairs: np.ndarray | None = None) -> Anchor:
        """A pose of the motion with bounds for the given pairs (all by default); the rest unknown."""
        q_arm = motion.arm_at(fraction)
        level = np.zeros(self.collision.pair_count, dtype=np.int8)
        if pairs is not None and pairs.size <= self.FEW_PAIRS:
            # coal alone beats the capsule pass for a handful of pairs
            bound = np.full(self.collision.pair_count, -np.inf)
            anchor = Anchor(fraction, q_arm, bound, level)
            self._refine(anchor, pairs, motion, 1)
            return anchor
        self.collision.pose(q_arm, motion.gripper_middle)
        return Anchor(fraction, q_arm, self.collision.bounds() - motion.reserve, level)

    def _reusable_end(self, gripper_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The last accepted end pose, its bounds, and how far this motion's gripper range reaches beyond the one
        they were judged over (the gripper's lever applies to that): they stand in for the start's bounds when the
        arm is still near it."""
        if self._last_end is None:
            return None
        last, (old_low, old_high) = self._last_end
        low, high = gripper_range
        return last.q_arm, last.bound, max(old_low - low, high - old_high, 0.0)

    def _refine(self, anchor: Anchor, pairs: np.ndarray, motion: Motion, level: int, tabulated: bool = True) -> None:
        """Tighten the bounds of these pairs to the given level at the anchor's pose (the fingers' table
        first, unless told to measure with coal alone)."""
        collision = self.collision
        if motion.gripper_moves and tabulated:
            pairs = self._sweep_fingers(anchor, pairs, motion)
        sweep = pairs[:0]
        if level >= 2 and motion.gripper_moves:
            # the sweep below samples the gripper's middle value too: these skip the single query at it
            swept = (anchor.level[pairs] < 2) & (motion.reserve[pairs] > 0)
            sweep, pairs = pairs[swept], pairs[~swept]
        todo = pairs[anchor.level[pairs] < min(level, 1)]
        if todo.size:
            collision.pose(anchor.q_arm, motion.gripper_middle)
            anchor.bound[todo] = collision.exact(todo) - motion.reserve[todo]
            anchor.level[todo] = 1
        if sweep.size == 0:
            return
        # coal at a few gripper values along its range, shared by the pairs; then each pair on its own
        coarse = [
            self._pose_with_gripper(anchor.q_arm, motion, fraction).exact(sweep).tolist()
            for fraction in self.COARSE_FRACTIONS
        ]
        for row, pair in enumerate(sweep.tolist()):
            anchor.bound[pair] = self._gripper_range_bound(anchor.q_arm, motion, pair, [ends[row] for ends in coarse])
        anchor.level[sweep] = 2

    def _gripper_range_bound(self, q_arm: np.ndarray, motion: Motion, pair: int, coarse: list[float]) -> float:
        """A lower bound on one pair's clearance at this arm pose over the gripper's range, from coal's clearances
        at the coarse gripper samples, halving only the intervals where the pair is in doubt: over an interval a
        clearance dips below the mean of its ends by at most the gripper's lever times half the interval's travel
        (the pair's reserve times the interval's share of the range). On plain floats: it runs per pair, often."""
        reserve, threshold = float(motion.reserve[pair]), float(motion.threshold[pair])
        fractions = self.COARSE_FRACTIONS
        if min(coarse) < threshold:
            # measured below its threshold at a gripper value of the range, it has no bound at or above it: halving
            # down to the resolution (dozens of queries, on every refused motion) would only settle how far below
            return min(
                (coarse[k] + coarse[k + 1]) / 2 - reserve * (fractions[k + 1] - fractions[k])
                for k in range(len(fractions) - 1)
            )
        bound = math.inf
        intervals = [(fractions[k], coarse[k], fractions[k + 1], coarse[k + 1]) for k in range(len(fractions) - 1)]
        while intervals:
            a, clearance_a, b, clearance_b = intervals.pop()
            dip = reserve * (b - a)
            low = (clearance_a + clearance_b) / 2 - dip
            if low >= threshold or dip <= self.SWEEP_RESOLUTION:
                bound = min(bound, low)
                continue
            middle = (a + b) / 2
            clearance = self._pose_with_gripper(q_arm, motion, middle).exact_one(pair)
            intervals += [(a, clearance_a, middle, clearance), (middle, clearance, b, clearance_b)]
        return bound

    def _sweep_fingers(self, anchor: Anchor, pairs: np.ndarray, motion: Motion) -> np.ndarray:
        """Prove the finger pairs the tabulated sweep clears over the gripper's whole range (level 2 at
        once, no coal); the pairs left to measure."""
        sweep = self.collision.gripper_sweep
        fingers = sweep.sweepable(pairs) & (anchor.level[pairs] < 2)
        if not fingers.any():
            return pairs
        self.collision.pose(anchor.q_arm, motion.gripper_middle)
        measured = pairs[fingers]
        clearance = sweep.clearances(measured, motion.gripper_from, motion.gripper_to)
        proven = clearance >= motion.threshold[measured]
        if not proven.any():
            return pairs
        anchor.bound[measured[proven]] = clearance[proven]
        anchor.level[measured[proven]] = 2
        fingers[fingers] = proven
        return pairs[~fingers]

    def _pose_with_gripper(self, q_arm: np.ndarray, motion: Motion, fraction: float) -> CollisionModel:
        """Pose the arm at q_arm and the gripper this far along its motion; the collision model, to measure."""
        self.collision.pose(q_arm, motion.gripper_from + fraction * (motion.gripper_to - motion.gripper_from))
        return self.collision

    def _settle(self, anchor: Anchor, motion: Motion, where: str, pairs: np.ndarray | None = None) -> Verdict:
        """Tighten every pair (of these) the capsules cannot clear, and refuse if one is truly too close."""
        for level in (1, 2) if motion.gripper_moves else (1,):
            if pairs is None:
                weak = (anchor.bound < motion.threshold).nonzero()[0]
            else:
                weak = pairs[anchor.bound[pairs] < motion.threshold[pairs]]
            if weak.size == 0:
                return ACCEPTED
            self._refine(anchor, weak, motion, level)
            if level == 1 and motion.gripper_moves:
                # coal measured these with the gripper at its middle value, one of those the motion passes: one
                # already below its threshold is refused here, before the sweep over the gripper's range
                measured = weak[anchor.level[weak] == 1]
                clearance = anchor.bound[measured] + motion.reserve[measured]
                below = clearance < motion.threshold[measured]
                if below.any():
                    worst = int(np.argmin(np.where(below, clearance - motion.threshold[measured], np.inf)))
                    return Verdict(False, self._describe(measured[worst], clearance[worst], where))
        return self._violation(anchor, motion.threshold, where)

    def _violation(self, anchor: Anchor, threshold: np.ndarray, where: str) -> Verdict:
        below = ((anchor.level > 0) & (anchor.bound < threshold)).nonzero()[0]
        if below.size == 0:
            return ACCEPTED
        worst = below[np.argmin(anchor.bound[below] - threshold[below])]
        return Verdict(False, self._describe(worst, anchor.bound[worst], where))

    def _describe(self, pair: int, clearance: float, where: str) -> str:
        first, second = self.collision.pair_names(pair)
        return f"{first} would come within {clearance:.3f} m of {second}{where}"
