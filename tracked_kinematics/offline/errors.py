"""
The error types of the offline ring.

A bag that cannot give what was asked, a bad option, a controllers file that cannot be
converted.

All derive from :class:`tracked_kinematics.core.errors.TrackedKinematicsError`, so that
:func:`tracked_kinematics.offline.cli.common.run_main` reports them, and the core's own
errors, as one line with an exit status, and lets anything else surface as a traceback.
"""

from tracked_kinematics.core.errors import TrackedKinematicsError


class BagError(TrackedKinematicsError):
    """A bag cannot give what was asked; the message is one line for the user."""


class UsageError(TrackedKinematicsError):
    """An invalid option value (exit status 2)."""


class DdcError(TrackedKinematicsError):
    """A controllers file that cannot be converted; the message is one line for the user."""
