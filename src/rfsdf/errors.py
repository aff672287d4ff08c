"""The one exception type that the CLI turns into a single error line."""

__all__ = ["RfsdfError"]


class RfsdfError(ValueError):
    """Bad input: a file, a field and a reason, meant to be shown as one line."""
