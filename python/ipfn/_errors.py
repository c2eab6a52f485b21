"""The exceptions ipfn raises (the compiled module raises these classes)."""


class IpfnError(Exception):
    """ipfn failed: the message is the command line's one line (what failed, what to do)."""


class InputError(IpfnError, ValueError):
    """Bad input: a missing or damaged file, an impossible size, an unknown option.

    The command line exits with code 2 for the same message.
    """
