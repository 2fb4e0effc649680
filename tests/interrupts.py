"""Child processes that a test's Ctrl+C reaches, however the suite itself was started."""

import signal


def ctrl_c_reaches():
    """preexec_fn for a child that a test stops with SIGINT: a shell starts a background job with SIGINT ignored,
    the child inherits that, and Python keeps an inherited SIG_IGN, so the child would never see the test's Ctrl+C.
    Set to its default, it becomes Python's KeyboardInterrupt again, as in a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
