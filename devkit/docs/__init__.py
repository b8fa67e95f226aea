"""The docs site's generated pages (run `python -m devkit.docs.generate`): the env family pages, the CLI, kwarg
and term references, and the benchmarks index."""
