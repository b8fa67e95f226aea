"""The benchmarks: each measures one claim and, with `--markdown docs/benchmarks/NAME.md`, writes its page
through devkit.report (run from the repository root: `python -m devkit.bench.NAME`)."""

# the twelve Sim IDs of the four seed robots' Reach, Push and Pick-and-Place, which the step and make benches measure
SIM_IDS = [
    f"{robot}{task}Sim-v0" for robot in ("UR5e", "VX300S", "RX200", "NED2") for task in ("Reacher", "Push", "PnP")
]
