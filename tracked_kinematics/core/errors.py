"""
The error types of the numerical core.

All derive from :class:`TrackedKinematicsError` (and ValueError), so a front door reports them on
one line and lets anything else surface as a traceback.
"""


class TrackedKinematicsError(ValueError):
    """Base of the package's own errors; the message is one line for the user."""


class IdentificationError(TrackedKinematicsError):
    """The data cannot give a trustworthy model; the message says why, on one line."""


class ExcitationError(IdentificationError):
    """Too little motion, turning or straight driving to identify a parameter."""


class FitError(IdentificationError):
    """The optimiser did not converge, or converged to an invalid model."""


class SensorDataError(TrackedKinematicsError):
    """A reference sensor's data that cannot be used (a gyro without rates, saturated; no fix)."""


class PlanningError(TrackedKinematicsError):
    """A planning request that cannot be met; the message says why, on one line."""


class InvalidParameters(TrackedKinematicsError):
    """Parameter values, or a parameter file, that cannot be used; the message names them."""
