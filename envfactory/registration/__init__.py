"""How an env ID comes to exist: the spec folders' registration blocks read into gymnasium's registry
(registry.py), the user's recorded folders (user_config.py), and the validation outcomes remembered across
processes so that a broken family stays out without being compiled again (validation_cache.py)."""
