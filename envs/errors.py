"""The one error type a user can cause: it carries a one-sentence message."""

__all__ = ["InvalidEnvironment", "UserError"]


class UserError(ValueError):
    """A bad input the user can fix (bad file, bad angle, unknown name, ...).

    The CLI prints its message as one sentence and exits with status 2.
    """


class InvalidEnvironment(UserError):
    """An environment file or name that cannot be loaded or fails validation."""
