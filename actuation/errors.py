"""Actuation's exception hierarchy: pyserial/OS errors are translated into these at the boundary."""


class ActuationError(Exception):
    """A base that cannot be reached or driven. The message is one line naming the port/device."""


class KobukiLinkError(ActuationError):
    """The serial link to the Kobuki is missing, closed, silent or refused."""


class DeadmanTrippedError(ActuationError):
    """The dead-man stopped the base (the control process went quiet) and ignores motion commands
    until `KobukiBase.rearm()` is called explicitly."""
