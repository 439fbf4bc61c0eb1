"""Actuation's exception hierarchy: pyserial/OS errors are translated into these at the boundary."""


class ActuationError(Exception):
    """A base that cannot be reached or driven. The message is one line naming the port/device."""


class KobukiLinkError(ActuationError):
    """The serial link to the Kobuki is missing, closed, silent or refused."""
