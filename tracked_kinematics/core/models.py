"""
Motion models: measured track speeds -> body twist, with a parameter vector.

A model is ``twist(p, v_left, v_right)`` with its Jacobian in ``p``, registered by name; the
identifier fits ``p``, the estimator tracks it, odometry and planning integrate the twist.
See docs/model.md, "Motion models" and "Adding a model".
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .integration import integrate
from .kinematics import IcrParams


def _icr_twist(v_left, v_right, y_left, y_right, x, with_speeds=True):
    """
    Twist (..., 3) and its derivatives in ``(y_left, y_right, x)`` and in ``(V_l, V_r)``.

    Martinez eqs. (7)-(9) in the ROS frame:
    ``v_x = (V_r y_left - V_l y_right) / (y_left - y_right)``. The derivatives are filled in
    place (the identification's Jacobian calls this at every evaluation); ``with_speeds``
    False: None for the speeds' (those models hold the scales).
    """
    span = y_left - y_right
    w = (v_right - v_left) / span
    v_x = (v_right * y_left - v_left * y_right) / span
    shape = np.broadcast_shapes(np.shape(w), np.shape(v_x), np.shape(x))
    twist = np.empty(shape + (3,))
    twist[..., 0] = v_x
    twist[..., 1] = -x * w
    twist[..., 2] = w
    dw_dyl = -w / span
    dw_dyr = w / span
    d_icr = np.zeros(shape + (3, 3))
    d_icr[..., 0, 0] = -w * y_right / span
    d_icr[..., 0, 1] = w * y_left / span
    d_icr[..., 1, 0] = -x * dw_dyl
    d_icr[..., 1, 1] = -x * dw_dyr
    d_icr[..., 1, 2] = -w
    d_icr[..., 2, 0] = dw_dyl
    d_icr[..., 2, 1] = dw_dyr
    if not with_speeds:
        return twist, d_icr, None
    inv = 1.0 / span
    d_speeds = np.empty(shape + (3, 2))
    d_speeds[..., 0, 0] = -y_right * inv
    d_speeds[..., 0, 1] = y_left * inv
    d_speeds[..., 1, 0] = x * inv
    d_speeds[..., 1, 1] = -x * inv
    d_speeds[..., 2, 0] = -inv
    d_speeds[..., 2, 1] = inv
    return twist, d_icr, d_speeds


@dataclass(frozen=True, slots=True)
class Parameter:
    """
    One entry of a model's parameter vector, with what the identification needs of it.

    Attributes
    ----------
    name, ros_name : str
        Name in the parameter vector; name in messages and terrain files (``icr.y_left``).
    excited_by : str
        The driving that identifies it: ``'turning'``, ``'straight'`` or ``''`` (either).
    bounds, box : tuple of float
        Physical bounds of least squares; finite search box of a global method (None: bounds).
    per_track_width : bool
        ``bounds``, ``box`` and the standard-error limit are in track widths.
    std_checked : bool
        The fit refuses it beyond the standard-error limit of its kind (``identify.STD_LIMITS``).

    """

    name: str
    ros_name: str = ''
    excited_by: str = ''
    bounds: tuple = (-np.inf, np.inf)
    box: tuple | None = None
    per_track_width: bool = False
    std_checked: bool = False

    def __post_init__(self):
        if not self.ros_name:
            object.__setattr__(self, 'ros_name', self.name)


class MotionModel(ABC):
    """
    Base of all motion models, for a ``track_width`` in m (``B`` in Fink & Stump).

    Class attributes: ``name``/``aliases`` (registry), ``parameters`` (the entries of ``p``),
    ``linear`` (twist linear in the track speeds), ``constant_icr`` (:meth:`as_icr` is the model
    itself), ``baseline`` (what a user has without this package), ``plan_name``.
    """

    name = ''
    aliases: tuple[str, ...] = ()
    parameters: tuple[Parameter, ...] = ()
    param_names: tuple[str, ...] = ()
    linear = True
    constant_icr = False
    baseline = False
    plan_name: str | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if 'parameters' in cls.__dict__:
            cls.param_names = tuple(p.name for p in cls.parameters)

    @classmethod
    def build(cls, track_width: float, scales=(1.0, 1.0)) -> MotionModel:
        """Build the model; ``scales`` are the fixed encoder scales of a model without any."""
        return cls(track_width)

    def __init__(self, track_width: float):
        track_width = float(track_width)
        if not np.isfinite(track_width) or track_width <= 0.0:
            raise ValueError(f'track_width must be a finite number > 0 m, got {track_width!r}')
        self.track_width = track_width

    @property
    def n_params(self) -> int:
        """Length of the parameter vector."""
        return len(self.param_names)

    def parameter(self, name: str) -> Parameter:
        """Return the declaration of parameter ``name`` (unbounded, unchecked if undeclared)."""
        return next((p for p in self.parameters if p.name == name), None) or Parameter(name)

    def guess(self, chi: float, segments) -> np.ndarray:
        """Start a fit: the model as a drive of steering efficiency ``chi`` (Martinez eq. 16)."""
        return self.initial().astype(float)

    def start_from(self, icr: IcrParams) -> np.ndarray | None:
        """Start of a fit from a base terrain file's ICR model, or None (:meth:`guess`)."""
        return None

    def from_icr(self, icr: IcrParams) -> np.ndarray | None:
        """Parameter vector of a terrain file's ICR model, or None if this model has none."""
        return None

    @abstractmethod
    def initial(self) -> np.ndarray:
        """Parameter vector that makes this model ideal differential drive."""

    @abstractmethod
    def twist_and_jacobian(self, p, v_left, v_right):
        """
        Body twist (N, 3; m/s, m/s, rad/s) and its Jacobian ``d twist / d p`` (N, 3, P).

        ``v_left``, ``v_right`` are the measured (nominal) track speeds, m/s.
        """

    def twist(self, p, v_left, v_right):
        """Body twist ``v_x, v_y, w`` (m/s, m/s, rad/s) from measured track speeds."""
        v_left, v_right = np.broadcast_arrays(np.asarray(v_left, float),
                                              np.asarray(v_right, float))
        twist, _ = self.twist_and_jacobian(p, v_left.ravel(), v_right.ravel())
        shape = v_left.shape
        return (twist[:, 0].reshape(shape), twist[:, 1].reshape(shape),
                twist[:, 2].reshape(shape))

    def increments(self, p, d_left, d_right, dt):
        """
        Body-frame increments ``(dx, dy, dtheta)`` over steps of measured track travel (m).

        ``dt`` (s) is unused by linear models; for the others a step with ``dt <= 0`` adds nothing.
        """
        if self.linear:
            return self.twist(p, d_left, d_right)
        dt = np.asarray(dt, dtype=float)
        ok = dt > 0.0
        safe_dt = np.where(ok, dt, 1.0)
        v_x, v_y, w = self.twist(p, np.asarray(d_left) / safe_dt, np.asarray(d_right) / safe_dt)
        scale = np.where(ok, dt, 0.0)
        return v_x * scale, v_y * scale, w * scale

    def integrate(self, p, d_left, d_right, dt, pose0=(0.0, 0.0, 0.0)):
        """Poses after each step of measured track travel (see :func:`integration.integrate`)."""
        return integrate(*self.increments(p, d_left, d_right, dt), pose0=pose0)

    def as_icr(self, p) -> IcrParams | None:
        """Return the constant-ICR terrain model equal to this one, or None if none is."""
        return None

    def __repr__(self):
        return f'{type(self).__name__}(track_width={self.track_width!r})'


class IdealDiffDrive(MotionModel):
    """Ideal differential drive, Fink & Stump Table I (row 1): ``w = (V_r - V_l) / B``."""

    name = 'ideal'
    parameters = ()
    constant_icr = True
    baseline = True
    plan_name = 'ideal'

    def initial(self):
        return np.zeros(0)

    def from_icr(self, icr):
        return self.initial()

    def twist_and_jacobian(self, p, v_left, v_right):
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        v_x = 0.5 * (v_left + v_right)
        w = (v_right - v_left) / self.track_width
        twist = np.stack([v_x, np.zeros_like(v_x), w], axis=-1)
        return twist, np.zeros(twist.shape + (0,))

    def as_icr(self, p):
        return IcrParams.ideal(self.track_width)


class EffectiveWheelBase(MotionModel):
    """
    Effective wheel-base model, Fink & Stump Table I (row 2): ``w = alpha (V_r - V_l) / B``.

    Equal to the symmetric ICR model of Martinez sec. 4.2 with ``chi = alpha``.
    """

    name = 'effective_wheel_base'
    aliases = ('symmetric',)
    parameters = (Parameter('alpha', 'chi', 'turning', (0.05, 1.0), std_checked=True),)
    constant_icr = True
    plan_name = 'effective'

    def initial(self):
        return np.ones(1)

    def guess(self, chi, segments):
        return np.array([chi], dtype=float)

    def from_icr(self, icr):
        return np.array([icr.chi])

    def twist_and_jacobian(self, p, v_left, v_right):
        alpha = float(np.asarray(p, float)[0])
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        w_ideal = (v_right - v_left) / self.track_width
        zero = np.zeros_like(w_ideal)
        twist = np.stack([0.5 * (v_left + v_right), zero, alpha * w_ideal], axis=-1)
        jac = np.stack([zero, zero, w_ideal], axis=-1)[..., None]
        return twist, jac

    def as_icr(self, p):
        return IcrParams.symmetric(self.track_width, float(np.asarray(p, float)[0]))


# Tread ICRs lie outside the track centrelines (Martinez sec. 3: slip only moves them
# outwards), which keeps 0 < chi <= 1 whatever the eccentricity; a tracked vehicle shows them
# within 2 B of the centre and 1 B ahead or behind. Encoder scales stay near 1.
ICR_PARAMETERS = (
    Parameter('y_left', 'icr.y_left', 'turning', (0.5, 10.0), (0.5, 2.0), True, True),
    Parameter('y_right', 'icr.y_right', 'turning', (-10.0, -0.5), (-2.0, -0.5), True, True),
    Parameter('x', 'icr.x', 'turning', (-5.0, 5.0), (-1.0, 1.0), True, True),
)
"""The tread ICRs ``(y_left, y_right, x)`` of Martinez eqs. (7)-(9), bounds in track widths."""
SCALE_PARAMETERS = (
    Parameter('scale_left', 'scale.left', 'straight', (0.5, 2.0), (0.8, 1.2), std_checked=True),
    Parameter('scale_right', 'scale.right', 'straight', (0.5, 2.0), (0.8, 1.2),
              std_checked=True),
)
"""The encoder scale corrections of Martinez eqs. (20)-(21)."""


class ConstantIcr(MotionModel):
    """
    Constant tread ICRs, Martinez et al. (2005) eqs. (7)-(9), optionally with scales.

    ``with_scales`` also fits ``scale_left``, ``scale_right`` (eqs. 20-21; else fixed ``scales``).
    Registered as ``icr_scales`` and, through :class:`FixedScalesIcr`, ``icr``.
    """

    name = 'icr_scales'
    parameters = ICR_PARAMETERS + SCALE_PARAMETERS
    linear = True
    constant_icr = True
    plan_name = 'icr'

    def __init__(self, track_width, with_scales=True, scales=(1.0, 1.0)):
        super().__init__(track_width)
        self.with_scales = bool(with_scales)
        self.fixed_scales = (float(scales[0]), float(scales[1]))
        self.name = 'icr_scales' if self.with_scales else 'icr'
        self.parameters = ICR_PARAMETERS + (SCALE_PARAMETERS if self.with_scales else ())
        self.param_names = tuple(p.name for p in self.parameters)

    def initial(self):
        half = 0.5 * self.track_width
        p = [half, -half, 0.0]
        return np.array(p + [1.0, 1.0] if self.with_scales else p)

    def from_icr(self, icr: IcrParams) -> np.ndarray:
        """Parameter vector of an :class:`IcrParams`."""
        p = [icr.y_left, icr.y_right, icr.x]
        return np.array(p + [icr.scale_left, icr.scale_right] if self.with_scales else p)

    def start_from(self, icr):
        return self.from_icr(icr)

    def guess(self, chi, segments):
        p = self.initial().astype(float)
        half = 0.5 * self.track_width / chi
        p[0], p[1] = half, -half
        return p

    def _scales(self, p):
        return (p[3], p[4]) if self.with_scales else self.fixed_scales

    def twist(self, p, v_left, v_right):
        # The hot path of odometry over whole logs: no Jacobian.
        p = np.asarray(p, float)
        scale_left, scale_right = self._scales(p)
        v_left = scale_left * np.asarray(v_left, float)
        v_right = scale_right * np.asarray(v_right, float)
        span = p[0] - p[1]
        w = (v_right - v_left) / span
        return (v_right * p[0] - v_left * p[1]) / span, -p[2] * w, w

    def twist_and_jacobian(self, p, v_left, v_right):
        p = np.asarray(p, float)
        scale_left, scale_right = self._scales(p)
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        twist, d_icr, d_speeds = _icr_twist(scale_left * v_left, scale_right * v_right,
                                            p[0], p[1], p[2], self.with_scales)
        if not self.with_scales:
            return twist, d_icr
        jac = np.empty(d_icr.shape[:-1] + (5,))
        jac[..., :3] = d_icr
        jac[..., 3] = d_speeds[..., 0] * v_left[..., None]
        jac[..., 4] = d_speeds[..., 1] * v_right[..., None]
        return twist, jac

    def as_icr(self, p):
        p = np.asarray(p, float)
        scale_left, scale_right = self._scales(p)
        return IcrParams(self.track_width, p[0], p[1], p[2], scale_left, scale_right)


class FixedScalesIcr(ConstantIcr):
    """Constant tread ICRs with fixed encoder scales: the registry's ``icr``."""

    name = 'icr'
    parameters = ICR_PARAMETERS
    plan_name = None

    def __init__(self, track_width, scales=(1.0, 1.0)):
        super().__init__(track_width, with_scales=False, scales=scales)

    @classmethod
    def build(cls, track_width, scales=(1.0, 1.0)):
        return cls(track_width, scales)


class GeneralKinematicSlip(MotionModel):
    """
    General kinematic slip model, Fink & Stump (eq. 2 and Table I, row 3).

    ``v = [v_x, 0, v_theta] + C(v_x, v_theta) alpha``, ``C`` block-diagonal with rows::

        c_x     = [v_x, |v_theta|, v_x |v_theta|]
        c_y     = [v_x,  v_theta,  v_x  v_theta ]
        c_theta = [v_x,  v_theta,  v_x  v_theta ]
    """

    name = 'general_slip'
    # alpha1, alpha4, alpha7 multiply v_x alone: straight driving identifies them.
    parameters = tuple(Parameter(f'alpha{i}', excited_by='straight' if i % 3 == 1 else 'turning')
                       for i in range(1, 10))
    linear = False
    plan_name = 'general'

    def initial(self):
        return np.zeros(9)

    def twist_and_jacobian(self, p, v_left, v_right):
        p = np.asarray(p, float)
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        v_x = 0.5 * (v_left + v_right)
        v_t = (v_right - v_left) / self.track_width
        c_x = np.stack([v_x, np.abs(v_t), v_x * np.abs(v_t)], axis=-1)
        c_yt = np.stack([v_x, v_t, v_x * v_t], axis=-1)
        jac = np.zeros(v_x.shape + (3, 9))
        jac[..., 0, 0:3] = c_x
        jac[..., 1, 3:6] = c_yt
        jac[..., 2, 6:9] = c_yt
        twist = np.stack([v_x, np.zeros_like(v_x), v_t], axis=-1) + jac @ p
        return twist, jac

    def twist(self, p, v_left, v_right):
        # Prediction over whole logs (identification): no Jacobian.
        p = np.asarray(p, float)
        v_left = np.asarray(v_left, float)
        v_right = np.asarray(v_right, float)
        v_x = 0.5 * (v_left + v_right)
        v_t = (v_right - v_left) / self.track_width
        v_xt = v_x * v_t
        abs_t = np.abs(v_t)
        return (v_x + p[0] * v_x + p[1] * abs_t + p[2] * v_x * abs_t,
                p[3] * v_x + p[4] * v_t + p[5] * v_xt,
                v_t + p[6] * v_x + p[7] * v_t + p[8] * v_xt)


class AdaptiveIcr(MotionModel):
    """
    Tread ICRs parameterised over lateral acceleration and curvature (EKF paper, eq. 11).

    The source text lost the equations; reconstructed from what survives (six parameters, ICRs
    of ``|a|`` and ``|k|``, ideal on a straight line) as, in the ROS frame::

        y_left  =  B/2 + p1 |a| + p2 |k|
        y_right = -B/2 - p3 |a| - p4 |k|
        x       =        p5 |a| + p6 |k|

    with ``a = v w`` and ``k = w / max(|v|, |w| B / 2)`` of the ideal drive; the span is floored
    at ``B / 100``. See docs/model.md, "Motion models".
    """

    name = 'adaptive_icr'
    # The outward terms p1..p4 are >= 0; the search box is 2 B wide.
    parameters = tuple(Parameter(f'p{i}', excited_by='turning', bounds=(0.0, np.inf),
                                 box=(0.0, 2.0), per_track_width=True) for i in range(1, 5)) \
        + tuple(Parameter(f'p{i}', excited_by='turning', box=(-2.0, 2.0), per_track_width=True)
                for i in (5, 6))
    linear = False

    def initial(self):
        return np.zeros(6)

    def guess(self, chi, segments):
        p = self.initial().astype(float)
        if len(segments.dt):
            # The curvature terms put the ICRs where the efficiency guess does, at the median
            # curvature of the turning steps.
            _, curv = self.features(segments.d_left / segments.dt,
                                    segments.d_right / segments.dt)
            turning = curv[curv > 1e-3]
            if len(turning):
                outward = 0.5 * self.track_width * (1.0 / chi - 1.0) / float(np.median(turning))
                p[1] = p[3] = outward
        return p

    def features(self, v_left, v_right):
        """Absolute nominal lateral acceleration (m/s^2) and bounded curvature (1/m)."""
        v_left = np.asarray(v_left, float)
        v_right = np.asarray(v_right, float)
        v = 0.5 * (v_left + v_right)
        w = (v_right - v_left) / self.track_width
        accel = np.abs(v * w)
        denom = np.maximum(np.abs(v), 0.5 * self.track_width * np.abs(w))
        curv = np.divide(np.abs(w), denom, out=np.zeros_like(w), where=denom > 0.0)
        return accel, curv

    def icr(self, p, v_left, v_right):
        """ICR coordinates ``(y_left, y_right, x)`` at the given track speeds."""
        p = np.asarray(p, float)
        accel, curv = self.features(v_left, v_right)
        half = 0.5 * self.track_width
        return (half + p[0] * accel + p[1] * curv,
                -half - p[2] * accel - p[3] * curv,
                p[4] * accel + p[5] * curv)

    def _floored_icr(self, p, v_left, v_right):
        """Return the ICRs with their span floored at ``B / 100``, and where it acted."""
        y_left, y_right, x = self.icr(p, v_left, v_right)
        floor = 0.01 * self.track_width
        clipped = (y_left - y_right) < floor
        if np.any(clipped):
            mid = 0.5 * (y_left + y_right)
            y_left = np.where(clipped, mid + 0.5 * floor, y_left)
            y_right = np.where(clipped, mid - 0.5 * floor, y_right)
        return y_left, y_right, x, clipped

    def twist(self, p, v_left, v_right):
        # Prediction over whole logs (identification): no Jacobian.
        v_left = np.asarray(v_left, float)
        v_right = np.asarray(v_right, float)
        y_left, y_right, x, _ = self._floored_icr(p, v_left, v_right)
        span = y_left - y_right
        w = (v_right - v_left) / span
        return (v_right * y_left - v_left * y_right) / span, -x * w, w

    def twist_and_jacobian(self, p, v_left, v_right):
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        accel, curv = self.features(v_left, v_right)
        y_left, y_right, x, clipped = self._floored_icr(p, v_left, v_right)
        twist, d_icr, _ = _icr_twist(v_left, v_right, y_left, y_right, x, False)
        # Chain rule through d(y_left, y_right, x) / dp, which is sparse: y_left depends on
        # p1, p2 (times |a|, |k|), y_right on p3, p4 (times -|a|, -|k|), x on p5, p6. Where
        # the span floor acted, y_left and y_right no longer depend on p.
        free = (~clipped).astype(float)[..., None]
        accel, curv = accel[..., None], curv[..., None]
        jac = np.empty(twist.shape + (6,))
        for i, factor in enumerate((d_icr[..., 0] * free, -d_icr[..., 1] * free, d_icr[..., 2])):
            jac[..., 2 * i] = factor * accel
            jac[..., 2 * i + 1] = factor * curv
        return twist, jac


_MODELS: dict[str, type[MotionModel]] = {}


def register_model(cls: type[MotionModel]) -> type[MotionModel]:
    """Register a model class by ``name`` and ``aliases`` (a decorator); ValueError if taken."""
    for name in (cls.name,) + tuple(cls.aliases):
        if _MODELS.get(name, cls) is not cls:
            raise ValueError(f'motion model {name!r} is already registered')
    for name in (cls.name,) + tuple(cls.aliases):
        _MODELS[name] = cls
    return cls


def unregister_model(name: str) -> None:
    """Remove a registered model, with its aliases (nothing for an unknown name)."""
    cls = _MODELS.get(name)
    for key in [k for k, v in _MODELS.items() if v is cls]:
        del _MODELS[key]


def model_class(name: str) -> type[MotionModel]:
    """Return the class registered under ``name``; ValueError (listing the known) for another."""
    try:
        return _MODELS[name]
    except KeyError:
        raise ValueError(f'unknown motion model {name!r}; choose one of '
                         f'{", ".join(model_names())}') from None


def model_names(aliases: bool = True) -> tuple[str, ...]:
    """Return the registered names in registration order, with or without the aliases."""
    return tuple(n for n, cls in _MODELS.items() if aliases or n == cls.name)


for _cls in (IdealDiffDrive, EffectiveWheelBase, FixedScalesIcr, ConstantIcr,
             GeneralKinematicSlip, AdaptiveIcr):
    register_model(_cls)

MODEL_NAMES = model_names()
"""The models of this module (``symmetric`` too); :func:`model_names` has every registered."""


def make_model(name: str, track_width: float) -> MotionModel:
    """Build a motion model by name for ``track_width`` (m); ValueError for an unknown one."""
    return model_class(name).build(track_width)
