"""
The error types of the offline ring: bags, options, controllers files.

All derive from :class:`~tracked_kinematics.core.errors.TrackedKinematicsError`: the tools
report them as one line with an exit status.
"""

from tracked_kinematics.core.errors import TrackedKinematicsError


class BagError(TrackedKinematicsError):
    """A bag cannot give what was asked; the message is one line for the user."""


class UsageError(TrackedKinematicsError):
    """An invalid option value (exit status 2)."""


class DdcError(TrackedKinematicsError):
    """A controllers file that cannot be converted; the message is one line for the user."""
