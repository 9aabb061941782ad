"""The error of one input the product refuses: a photo, its sidecar, the light or eyes given with it."""


class InputError(ValueError):
    """A problem with one input; the message names the file and the problem on one line."""
