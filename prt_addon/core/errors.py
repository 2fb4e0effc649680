"""Problems told to the user in one sentence that names what is wrong, found before any work is spent."""


class InputError(Exception):
    """Bad input: an object that cannot be baked, a setting out of range, a file that cannot be read. Other
    objects still bake; a command stops with exit code 1 and this sentence."""


class StaleBake(InputError):
    """A stored bake that no longer fits its mesh (or is missing): never applied, to be rebaked."""
