"""Ctrl-C in long work that saves as it goes (a fit, wear updates): stop at the next safe point.

Python raises ``KeyboardInterrupt`` wherever the main thread is when the signal arrives. Inside
JAX that can be a callback whose exceptions are printed and dropped (``Exception ignored in:
_xla_gc_callback``): the interrupt was lost and a fit ran to its end with exit code 0 (1 of 4
tries). :func:`stop_at_safe_points` replaces the handler for the duration of the work: the
first SIGINT only sets a flag, which the work reads between iterations (:meth:`Interrupt.check`,
after the checkpoint is written) and answers by raising ``KeyboardInterrupt`` there; a second
SIGINT raises at once, as usual. Where the handler cannot be replaced (not the main thread, or
someone else's handler installed) nothing changes.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

#: Seconds after a first Ctrl-C before the work says it is still finishing its iteration.
NOTICE_AFTER_S = 2.0


class Interrupt:
    """Whether a Ctrl-C asked the work to stop (:func:`stop_at_safe_points`)."""

    def __init__(self):
        self.requested = False

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if a Ctrl-C arrived; call it where stopping loses nothing."""
        if self.requested:
            raise KeyboardInterrupt


@contextlib.contextmanager
def stop_at_safe_points(what: str = "the current iteration"):
    """Within the block a Ctrl-C sets the yielded :class:`Interrupt`'s flag; the work calls
    :meth:`Interrupt.check` between iterations. If the work has not stopped
    :data:`NOTICE_AFTER_S` seconds after the Ctrl-C (a long iteration, or one that compiles),
    one line on stderr says that it finishes ``what`` first and that a second Ctrl-C stops at once."""
    flag = Interrupt()
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield flag
        return
    timers: list[threading.Timer] = []

    def notice():
        print(f"jaxclear: stopping after {what}; Ctrl-C again to stop at once", file=sys.stderr, flush=True)

    def handler(signum, frame):
        if flag.requested:
            raise KeyboardInterrupt
        flag.requested = True
        timers.append(threading.Timer(NOTICE_AFTER_S, notice))
        timers[-1].daemon = True
        timers[-1].start()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, previous)
        for timer in timers:
            timer.cancel()
