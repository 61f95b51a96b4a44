"""User-facing errors.

Anything a user can cause (a bad scenario key, a missing file, a corrupt EXR, a NaN state)
raises :class:`UserError` with a one-line message that names the problem. The CLI prints
``renderlab: error: <message>`` on stderr and exits with code 2, without a traceback.
Programming errors stay ordinary exceptions.
"""


#: the longest message a UserError keeps: a user's value quoted without a bound is cut here, never printed whole
MAX_MESSAGE = 1000


class UserError(Exception):
    """An error caused by the user's input; its message is one line that names the problem (at most
    :data:`MAX_MESSAGE` characters)."""

    def __init__(self, message: str):
        text = " ".join(str(message).split())
        super().__init__(text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 1] + "…")


def run_main(entry, argv=None) -> int:
    """``python -m`` entry of a module's ``main(argv)``: a :class:`UserError` is one line on stderr
    (``renderlab: error: <message>``) and exit code 2, no traceback."""
    import sys

    try:
        return entry(argv)
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2
