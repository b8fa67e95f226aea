"""The benchmarks: each measures one claim and, with `--markdown docs/benchmarks/NAME.md`, writes its page
through devkit.report (run from the repository root: `python -m devkit.bench.NAME`)."""
