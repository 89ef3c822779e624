"""The root of slopelander's error types.

Every error a user can cause (a bad file, an out-of-range setting, a lost link)
derives from :class:`SlopelanderError`, so the command line can print its message
without a traceback while Python callers still catch the specific type.
"""


class SlopelanderError(Exception):
    """An error whose message is meant for the user."""
