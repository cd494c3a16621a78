"""Errors that the CLI turns into one clear line and exit status 2."""


class GinnError(Exception):
    """Base class of user-facing errors."""


class ConfigError(GinnError, ValueError):
    """A bad configuration value, flag or key."""


class SpecError(GinnError, ValueError):
    """A malformed problem spec; the message names the field path."""
