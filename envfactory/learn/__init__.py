"""Training, replay and demonstrations (the optional `[train]` extra).

Nothing here imports torch or Stable-Baselines3 at module level: the CLI
imports these modules without the extra and reports how to install it.
"""
