"""The repository's own Python, beside the library it measures and documents: the benchmarks (bench/, run as
`python -m devkit.bench.NAME`), the independent judges that tests and benchmarks share (oracles/), the page
writer every benchmark reports through (report.py), and the docs site's generators (docs/). The library never
imports it (tests/test_layers.py)."""
