"""The safety geometry's compiled kernels, in the order the proof uses them: the kinematic tree as arrays
(joints.py), per-pose capsule bounds (pose.py), a finger's sweep over a gripper range (finger_sweep.py), the
proof of a whole motion (motion.py) with its bisection of the pairs in doubt (bisection.py), the same proof
against the objects' bounding spheres (spheres.py), and the IK's damped least squares (damped_least_squares.py).
Callers reach them through serving.py's `kernels`: built ahead of time (native.py) where a C compiler allows,
numba's just-in-time form elsewhere, and interpreted while warmup.py builds them."""
