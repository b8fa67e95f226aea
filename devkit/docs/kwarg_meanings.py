"""What each gym.make kwarg means, for reference/kwargs.md.

The aliases themselves (kwarg -> spec path) live in the spec YAML (specs/_defaults.yaml and the task files'
`kwargs:` blocks) and reach the page from the composed specs; the schema carries types and defaults but no
prose, so the prose is kept here. The generator refuses to run while a shipped kwarg has no entry, or an
entry names a kwarg no shipped spec declares, so this list cannot fall behind the specs unnoticed.
"""

from __future__ import annotations

MEANINGS: dict[str, str] = {
    "seed": "Seed of the first reset() when it is called without one (the goal and cube draws follow from it).",
    "gui": "Open the simulator's window (PyBullet GUI; MuJoCo is headless). Sim IDs only.",
    "gazebo_gui": "The original suite's name for `gui`: opens the PyBullet window.",
    "reward_type": "`Dense` (weighted shaping terms) or `Sparse` (0 at the goal, else -1, with termination at "
    "the goal). Any letter case is accepted.",
    "ee_action_type": "Act in end-effector space (Cartesian position, solved by IK) instead of joint space.",
    "ee_yaw_action": "EE mode only, with delta actions: a fourth row, Δyaw, turns the tool about the vertical by "
    "`delta_coeff` times it (at most a half turn times `delta_coeff` a step), so a policy can square the gripper "
    "to a line, as Slide's strike needs. Joint mode turns the wrist through its own rows and has no such row.",
    "delta_action": "Actions are changes from the current pose (scaled by `delta_coeff`) instead of absolute targets.",
    "delta_coeff": "Scale of a delta action: the action box times this is the largest step.",
    "normalize_actions": "The policy acts in [-1, 1] on every row; each row is mapped onto its declared bounds.",
    "normalize_observations": "Every vector observation column (and both goals in goal envs) is scaled from its "
    "declared bounds to [-1, 1].",
    "environment_loop_rate": "The original suite's control loop rate, Hz. Here it bounds the cycle from below: "
    "`action_cycle_time` must be at least 1 / `environment_loop_rate`.",
    "action_cycle_time": "Seconds of motion one step lets pass (simulated in Sim, waited for on a real arm).",
    "action_speed": "Seconds the arm takes to reach each commanded joint target within a cycle.",
    "realtime_mode": "Step the physics at wall-clock rate in a background thread instead of inside step().",
    "use_kinect": "Add the scene camera's images (`rgb`, `depth`) to a Dict observation.",
    "log_internal_state": "Log every refused action and its reason (Python logging, INFO).",
    "max_joint_delta": "Largest change of any arm joint one action may command, rad; larger steps are refused.",
    "physics_fidelity": "`fast` simulates only the cycles whose outcome can depend on dynamics; `full` simulates "
    "every substep of every cycle (the reference).",
    "engine": "Physics engine of a Sim ID: `pybullet` or `mujoco` (same robot, scene, objects and checks).",
    "randomize": "Turn on the task's events (sampled physics) and sensing terms (noise, delays): Sim IDs only; "
    "see [Randomization](../concepts/randomization.md).",
    "allow_real_robot_motion": "Let a Real ID move the arm (the motion gate). Without it, commands are refused "
    "before they are sent; ALLOW_REAL_ROBOT_MOTION=1 also opens it.",
    "rosbridge_host": "Host of the rosbridge websocket a Real ID connects to.",
    "rosbridge_port": "Port of the rosbridge websocket a Real ID connects to.",
    "joint_state_timeout_s": "Real IDs: joint states older than this many seconds stop the arm and end the episode.",
    "cube_pose_timeout_s": "Real IDs: an object pose older than this many seconds ends the episode.",
    "deadman_s": "Real IDs: with no command for this many seconds the arm is stopped.",
    "auto_launch_cube_tracker": "Start the camera cube tracker from the env. True is refused: start the tracker "
    "yourself.",
    "cube_tracker_camera": "Camera the cube tracker runs on: `kinect2`, `zed2` or `d405`.",
    "cube_tracker_target_frame": "If set, object poses must be given in this frame (or transform to it).",
    "joint_states_topic": "Real IDs: the sensor_msgs/JointState topic the arm's state is read from.",
    "arm_command_topic": "Real IDs: the topic arm commands are published on.",
    "gripper_command_topic": "Real IDs: the topic gripper commands are published on.",
    "cube_pose_topic": "Real IDs: the geometry_msgs/PoseStamped topic the cube's pose is read from.",
    "random_cube_spawn": "Spawn the cube at a random offset (± the spawn offset in x and y) around its spawn "
    "position at every reset, instead of exactly there.",
    "random_puck_spawn": "Spawn the puck at a random offset (± the spawn offset in x and y) around its spawn "
    "position at every reset, instead of exactly there.",
    "random_lower_spawn": "Spawn the lower cube (the one the goal places) at a random offset (± the spawn "
    "offset in x and y) around its spawn position at every reset, instead of exactly there.",
    "random_upper_spawn": "Spawn the upper cube (the one stacked on the lower) at a random offset (± the spawn "
    "offset in x and y) around its spawn position at every reset, instead of exactly there.",
    "random_goal": "Draw the goal uniformly from the goal box at every reset, instead of the static goal.",
    "multi_goal": "Pick and place's lift stage: the current goal is the cube's spawn raised by `lift_height` until "
    "the cube gets there, then the place goal.",
    "lift_height": "Height of the lift stage's goal above the cube's spawn, m.",
}
