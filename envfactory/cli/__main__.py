"""`python -m envfactory.cli`: the `envfactory` command."""

from envfactory.cli.app import main

main()
