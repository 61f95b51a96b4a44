"""User-facing errors.

Anything a user can cause (a bad scenario key, a missing file, a corrupt EXR, a NaN state)
raises :class:`UserError` with a one-line message that names the problem. The CLI prints
``renderlab: error: <message>`` on stderr and exits with code 2, without a traceback.
Programming errors stay ordinary exceptions.
"""


class UserError(Exception):
    """An error caused by the user's input; its message is one line that names the problem."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
