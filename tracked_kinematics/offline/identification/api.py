"""
identify_icr's fit as one call: :class:`FitOptions` in, :class:`FitResult` out.

The ``identify_icr`` command line, ``calibration_drive`` and the demo all call :func:`fit`: it
checks the options, reads the base terrain file and the bags, fits (:mod:`.poses` from a
ground-truth pose, :mod:`.references` from a gyro, GNSS or a measured straight) and returns
the terrain values, the report and the table; :func:`write_fit` writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import (IdentificationError, InvalidParameters,
                                            SensorDataError)
from tracked_kinematics.core.identify.procedure import IdentifyOptions
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags import (EncoderSource, GroundTruthSource, IMU_AUTO,
                                             read_recordings)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.terrain_file import terrain_text
from tracked_kinematics.offline.tooling import (
    checked_encoders, IMU_MOUNT_KEYS, imu_mount_of, read_base_file, report_json,
    require_vehicle)
from tracked_kinematics.params import (
    check_values, icr_from_values, TERRAIN_DEFAULTS, TERRAIN_PARAMS)

from .combined import icr_from_pose_and_gyro
from .noise_constants import add_extras, gyro_aided_extras, gyro_extras
from .poses import icr_from_poses
from .references import icr_from_references
from .report import FitResult, TOOL

MODELS = ('symmetric',) + ident.FIT_MODELS
"""The models identify_icr fits and writes (``symmetric``: as ``effective_wheel_base``)."""


@dataclass(frozen=True, slots=True)
class FitOptions:
    """
    What identify_icr fits, from which bags (its options: docs/tools/identify_icr.md).

    Attributes
    ----------
    bags : tuple of str
        The bags.
    params : str or None
        Base terrain file: the vehicle, the starting point, the values a reference holds;
        its other parameters are copied to the output.
    track_width, sprocket_radius : float or None
        m; None: the base file's.
    encoders : EncoderSource
        Where the encoders are; its ``sprocket_radius`` is replaced by the vehicle's.
    ground_truth : GroundTruthSource or None
        The ground-truth pose.
    imu_topic, gnss_topic : str or None
        A gyro (sensor_msgs/Imu) and GNSS positions: a calibration without a pose (or
        with it) by :mod:`.references`.
    imu_delay : float or 'auto'
        s of the gyro stamps behind the encoders; 'auto' estimates it.
    imu_mount : tuple of float or None
        ``(roll, pitch, yaw)``, rad: the IMU in base_link, odometry_node's ``imu_mount.*``;
        None: the base file's (else 0 0 0). Written to the terrain file when given.
    gnss_antenna : tuple of float
        Position of the GNSS antenna in base_link, m.
    straight_distance : float or None
        The bags are one straight drive of this many metres.
    model : str
        Model to fit and write (:data:`MODELS`).
    spin_in_place : bool
        Measure chi on spin-in-place runs (Martinez eq. 16) instead of fitting segments.
    terrain : str or None
        Terrain name to write.
    identify : IdentifyOptions
        How the segments are fitted and the models compared; its ``ground_truth_delay``
        serves the spin runs and a pose reference too, its ``segment_length`` (0: every
        ground-truth sample) a reference's heading segments (0: 1 s).

    """

    bags: tuple
    params: str | None = None
    track_width: float | None = None
    sprocket_radius: float | None = None
    encoders: EncoderSource = EncoderSource()
    ground_truth: GroundTruthSource | None = None
    imu_topic: str | None = None
    imu_delay: float | str = 'auto'
    imu_mount: tuple | None = None
    gnss_topic: str | None = None
    gnss_antenna: tuple = (0.0, 0.0)
    straight_distance: float | None = None
    model: str = 'icr_scales'
    spin_in_place: bool = False
    terrain: str | None = None
    identify: IdentifyOptions = field(
        default_factory=lambda: IdentifyOptions(ground_truth_delay='auto'))

    @property
    def pose_and_gyro(self) -> bool:
        """Whether a pose and a gyro, and nothing else, are the references (:mod:`.combined`)."""
        return bool(self.ground_truth is not None and self.imu_topic and not self.gnss_topic
                    and self.straight_distance is None and not self.spin_in_place)

    @property
    def uses_references(self) -> bool:
        """Whether a gyro, GNSS or a measured straight is the reference (:mod:`.references`)."""
        return bool(self.imu_topic or self.gnss_topic or self.straight_distance is not None) \
            and not self.pose_and_gyro


def fit(options: FitOptions, *, date: str | None = None) -> FitResult:
    """
    Check the options, read the base file and the bags, fit; return what to print and write.

    Parameters
    ----------
    options : FitOptions
        What to fit.
    date : str, optional
        ISO 8601 time to record; default now.

    Returns
    -------
    FitResult

    Raises
    ------
    UsageError
        For options that contradict each other or a vehicle that cannot serve, before the
        bags are read.
    BagError, SensorDataError, ExcitationError, FitError
        From reading and fitting.

    """
    check_options(options)
    base_values, base, track_width, radius = _vehicle(options)
    encoders = replace(checked_encoders(options.encoders), sprocket_radius=radius)
    # Each bag read once, with every stream the fit uses: a pose fit also takes the bag's one
    # gyro topic, if it has one (_with_gyro); a pose and a gyro, the gyro given.
    given_gyro = options.uses_references or options.pose_and_gyro
    # The gyro read as odometry_node reads it (its imu_mount.*).
    mount = imu_mount_of(options.imu_mount, [(options.params, base_values)])
    recordings = read_recordings(
        options.bags, encoders, ground_truth=options.ground_truth,
        imu_topic=options.imu_topic if given_gyro else IMU_AUTO,
        gnss_topic=options.gnss_topic, progress=sys.stderr.isatty(), imu_mount=mount)
    if options.pose_and_gyro:
        found = icr_from_pose_and_gyro(recordings, options, options.imu_topic, track_width,
                                       radius, base=base, base_values=base_values, date=date)
    elif options.uses_references:
        found = icr_from_references(recordings, options, track_width, radius, base=base,
                                    base_values=base_values, date=date)
    else:
        found = _with_gyro(icr_from_poses(recordings, options, track_width, radius, base=base,
                                          base_values=base_values, date=date), recordings)
    if options.imu_mount is None:
        return found
    # The gyro constants are the mounted gyro's: the node is to read it the same way.
    return replace(found, values={**found.values, **dict(zip(IMU_MOUNT_KEYS, mount))})


def _with_gyro(found: FitResult, recordings) -> FitResult:
    """
    Add the gyro's constants to a pose fit whose bags carry one gyro topic, the same in each.

    The ICRs stay the pose fit's; ``imu_delay`` and ``gyro_scale`` (:func:`.noise_constants.
    gyro_extras`) let odometry_node's ``imu_topic`` and evaluate_model's ``--fuse-imu`` use
    the gyro at the right time. A gyro that cannot be read or timed adds a note, not an error.
    """
    if found.identification is None:    # spin in place: the ICRs alone
        return found
    topics = {r.gyro_topic for r in recordings}
    if len(topics) != 1 or not next(iter(topics)):
        return found
    topic = next(iter(topics))
    try:
        empty = next((r.name for r in recordings if r.gyro_t is None), None)
        if empty is not None:
            raise SensorDataError(f'{empty}: no Imu messages on {topic}')
        extras, gyro = gyro_extras(recordings, topic)
    except (SensorDataError, IdentificationError, ValueError) as err:
        return replace(found, lines=found.lines + (
            f'gyro {topic}: not used ({err}); imu_delay and gyro_scale not written',))
    values, report, lines = dict(found.values), dict(found.report), list(found.lines)
    add_extras(values, report, lines, extras)
    if gyro is not None and 'covariance.k_left' in values:
        # The gyro-aided odometry's own noise model, on its own windows (issue 35).
        add_extras(values, report, lines, gyro_aided_extras(
            values, gyro[0], float(found.report['track_width']),
            found.identification.min_speed))
    return replace(found, values=values, report=report, lines=tuple(lines))


def write_fit(found: FitResult, outputs: Outputs, options: FitOptions) -> None:
    """
    Write the terrain file, and the report and the plot when ``outputs`` plans them.

    ``outputs`` names them as identify_icr's flags: ``--output``, ``--report``, ``--plot``.
    """
    outputs.write_text('--output', terrain_text(found.values, tool=TOOL, date=found.date,
                                                note=found.note))
    if '--report' in outputs:
        outputs.write_text('--report', report_json(found.report))
    if '--plot' in outputs:
        from tracked_kinematics.offline.plots import plot_identification
        result = found.identification
        # The moving segments the fit used: those of min_travel, delay removed.
        segments = ident.build_segments(result.recordings, result.segment_length)
        with outputs.path('--plot') as tmp:
            plot_identification(tmp, result.recordings, result,
                                segments.select(segments.travel >= options.identify.min_travel))


def check_options(options: FitOptions) -> None:
    """
    Refuse options that contradict each other or that no fit can serve, before any work.

    Raises
    ------
    UsageError
        Naming identify_icr's flags.

    """
    if options.uses_references:
        _check_reference_options(options)
        return
    if options.ground_truth is None:
        raise UsageError('give --ground-truth-topic (a pose) or --imu-topic (a gyro)')
    unknown = [m for m in options.identify.compare if m not in ident.COMPARE_MODELS]
    if unknown:
        raise UsageError(f'--compare: unknown model {", ".join(unknown)}; choose from '
                         f'{", ".join(ident.COMPARE_MODELS)}')


def _check_reference_options(options: FitOptions) -> None:
    """Refuse option combinations the reference calibration cannot serve."""
    if options.gnss_topic and not (options.imu_topic or options.ground_truth):
        raise UsageError('--gnss-topic gives positions only: give --imu-topic (the heading) '
                         'as well')
    if options.straight_distance is not None and not options.imu_topic:
        raise UsageError('--straight-distance needs --imu-topic (to check that the drive is '
                         'straight)')
    if options.straight_distance is not None and options.gnss_topic:
        raise UsageError('give --straight-distance or --gnss-topic for the distance, not both')
    if options.spin_in_place:
        raise UsageError('--spin-in-place needs --ground-truth-topic, not --imu-topic')
    if options.model not in ('icr_scales', 'icr', 'symmetric'):
        raise UsageError(f'--model {options.model} needs a ground-truth pose; with '
                         '--imu-topic the constant-ICR model is fitted')


def _vehicle(options: FitOptions):
    """Read the base terrain values and check the vehicle dimensions."""
    base_values = read_base_file(TOOL, options.params)
    merged = {**TERRAIN_DEFAULTS, **{k: v for k, v in base_values.items()
                                     if k in TERRAIN_DEFAULTS}}
    if options.track_width is not None:
        merged['track_width'] = options.track_width
    if options.sprocket_radius is not None:
        merged['sprocket_radius'] = options.sprocket_radius
    # The values the fallback below builds a model from: a number each (not 'abc').
    problems = check_values([s for s in TERRAIN_PARAMS if s.name in (
        'track_width', 'sprocket_radius', 'scale.left', 'scale.right')], merged)
    if problems:
        raise UsageError(f'{options.params or "vehicle"}: {"; ".join(problems)}')
    require_vehicle({'--track-width': options.track_width if options.track_width is not None
                     else base_values.get('track_width'),
                     '--sprocket-radius': options.sprocket_radius
                     if options.sprocket_radius is not None
                     else base_values.get('sprocket_radius')})
    base = None
    if options.params:
        try:
            base = icr_from_values(merged)
        except InvalidParameters:
            # The ICRs of a file made for another track width: keep its scales only.
            try:
                base = IcrParams.ideal(merged['track_width'])
                base = IcrParams(base.track_width, base.y_left, base.y_right, 0.0,
                                 merged['scale.left'], merged['scale.right'])
            except ValueError as err:   # the user's track width or scales
                raise UsageError(str(err)) from None
    return base_values, base, float(merged['track_width']), float(merged['sprocket_radius'])
