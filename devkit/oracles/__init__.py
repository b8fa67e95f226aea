"""Independent judges, shared by tests and benchmarks: PyBullet's distance queries on the simulated scene
(bullet_judge.py), paired fast and full fidelity steps (fidelity_probe.py), and the makers' own meshes and
URDFs (maker_models.py). None of them judges the code by its own model."""
