"""Write the generated part of the docs site from the code and the specs.

    python -m devkit.docs.generate                  # rewrite every generated page and the scene pictures
    python -m devkit.docs.generate --no-pictures    # the pages only
    python -m devkit.docs.generate --check          # exit 1 naming each generated page that is out of date

The pages: envs/index.md and envs/<family>.md (one per shipped spec file, with its scene picture
img/envs/<family>.png), reference/cli.md, reference/kwargs.md, reference/terms.md and benchmarks/index.md
(the result pages beside it are written by the benchmark scripts themselves). `--check` compares the
Markdown only: the pictures come from the renderer and are not compared.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import imageio.v3 as iio

from devkit.docs import benchmark_index, env_pages, mdtext, reference_pages
from devkit.docs.render_scene import render

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"

# folders whose every page this script writes: a page carrying the banner that it no longer writes is stale
OWNED_FOLDERS = ("envs", "reference")


def pages() -> dict[str, str]:
    """Every generated page by its path under docs/."""
    families = env_pages.shipped_families()
    generated = {"envs/index.md": env_pages.index_page(families)}
    generated.update({family.page: env_pages.family_page(family) for family in families})
    generated["reference/cli.md"] = reference_pages.cli_page()
    generated["reference/kwargs.md"] = reference_pages.kwargs_page(families)
    generated["reference/terms.md"] = reference_pages.terms_page()
    generated["benchmarks/index.md"] = benchmark_index.index_page(DOCS / "benchmarks", REPO / "devkit" / "bench")
    return generated


def stale_pages(generated: dict[str, str], docs: Path = DOCS) -> list[str]:
    """Pages this script wrote once (they carry its banner) and no longer writes, e.g. of a removed spec file."""
    stale = []
    for folder in OWNED_FOLDERS:
        for path in sorted((docs / folder).glob("*.md")):
            relative = path.relative_to(docs).as_posix()
            if relative not in generated and path.read_text().startswith(mdtext.BANNER):
                stale.append(relative)
    return stale


def out_of_date(generated: dict[str, str], docs: Path = DOCS) -> list[str]:
    """One line per page under `docs` that differs from what the generator writes, is missing, or is stale."""
    problems = []
    for relative, text in generated.items():
        path = docs / relative
        if not path.exists():
            problems.append(f"docs/{relative}: missing")
        elif path.read_text() != text:
            problems.append(f"docs/{relative}: out of date")
    problems += [f"docs/{relative}: no longer generated (delete it)" for relative in stale_pages(generated, docs)]
    return problems


def write(generated: dict[str, str], docs: Path = DOCS) -> None:
    for relative, text in generated.items():
        path = docs / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            print(f"wrote docs/{relative}")
    for relative in stale_pages(generated, docs):
        (docs / relative).unlink()
        print(f"removed docs/{relative} (no longer generated)")


def write_pictures() -> None:
    for family in env_pages.shipped_families():
        path = DOCS / family.picture
        path.parent.mkdir(parents=True, exist_ok=True)
        iio.imwrite(path, render(family.picture_id, 0, env_pages.PICTURE_SEED), optimize=True)
        print(f"wrote docs/{family.picture} ({family.picture_id}, {path.stat().st_size // 1024} KB)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 naming each generated Markdown page that is out of date",
    )
    parser.add_argument("--no-pictures", action="store_true", help="write the pages, not the scene pictures")
    args = parser.parse_args(argv)
    generated = pages()
    if args.check:
        problems = out_of_date(generated)
        for problem in problems:
            print(problem, file=sys.stderr)
        if problems:
            print("run `python -m devkit.docs.generate` to bring the generated pages up to date", file=sys.stderr)
            return 1
        print(f"{len(generated)} generated pages up to date")
        return 0
    write(generated)
    if not args.no_pictures:
        write_pictures()
    return 0


if __name__ == "__main__":
    sys.exit(main())
