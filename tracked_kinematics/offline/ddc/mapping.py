"""
diff_drive_controller parameters -> the parameters of tracked_kinematics' nodes.

DDC's odometry is the tread-ICR model with ICRs at ``+-separation / 2`` and
``chi = 1 / wheel_separation_multiplier``; a multiplier below 1 is written as
``track_width = separation`` with ideal ICRs. The derivation and the mapping:
docs/tools/convert_diff_drive_params.md.
"""

from __future__ import annotations

from collections.abc import Mapping
import difflib
import math
import os
from typing import Any

from tracked_kinematics.offline.errors import DdcError
from tracked_kinematics.params import (check_values, COMMAND_LIMIT_PARAMS, ENCODER_INPUT_PARAMS,
                                       frame_id, icr_from_values, TERRAIN_PARAMS)

from .controllers import find_controller, load_controllers
from .conversion import AXES, Conversion
from .rcl_values import clean, fmt, read_bool, read_joints, read_number, read_positive, read_text

_AXIS_KEYS = tuple(f'{axis}.{name}' for axis in AXES for name in (
    'has_velocity_limits', 'has_acceleration_limits', 'has_jerk_limits', 'max_velocity',
    'min_velocity', 'max_acceleration', 'min_acceleration', 'max_deceleration',
    'max_acceleration_reverse', 'max_deceleration_reverse', 'max_jerk', 'min_jerk'))

# DDC keys (Humble to Jazzy, and the ROS 1 names) that have no counterpart, with the reason.
_NO_COUNTERPART = {
    'pose_covariance_diagonal':
        'odometry_node computes the pose covariance from its encoder noise model '
        '(covariance.k_left, covariance.k_right, covariance.floor): it grows with the travel '
        'instead of being a fixed diagonal',
    'twist_covariance_diagonal':
        'odometry_node computes the twist covariance from the same encoder noise model',
    'k_l': 'ROS 1 covariance factor; odometry_node has its own noise model (covariance.*)',
    'k_r': 'ROS 1 covariance factor; odometry_node has its own noise model (covariance.*)',
    'velocity_rolling_window_size':
        "odometry_node's twist is the mean over each publish period (publish_rate), from the "
        'travel, not a rolling mean of the last N updates',
    'publish_limited_velocity': 'cmd_vel_translator has no switch for it',
    'publish_cmd': 'ROS 1 name of publish_limited_velocity; cmd_vel_translator has no switch',
    'wheels_per_side':
        'odometry_node averages all the joints listed in left_joints / right_joints',
    'allow_multiple_cmd_vel_publishers':
        'cmd_vel_translator takes the latest command from any publisher',
    'preserve_turning_radius':
        'cmd_vel_translator always keeps the turning radius when it limits a command (it '
        'scales v_x and w together)',
    'type': 'the controller type: it identified the section',
    'use_sim_time': 'a parameter of every ROS node: set it where you start the nodes (the '
                    "launch file's use_sim_time)",
    'update_rate': "the controller's update rate: odometry_node integrates every joint_states "
                   "message (joint_state_broadcaster publishes at the controller_manager's "
                   'update_rate)',
    'is_async': 'a controller_manager setting of the controller',
    'thread_priority': 'a controller_manager setting of the controller',
    'params_file': 'a controller_manager setting of the controller',
    'fallback_controllers': 'a controller_manager setting of the controller',
}

_HANDLED = frozenset((
    'wheel_separation', 'wheel_separation_multiplier', 'wheel_radius',
    'left_wheel_radius_multiplier', 'right_wheel_radius_multiplier', 'wheel_radius_multiplier',
    'left_wheel_names', 'right_wheel_names', 'left_wheel', 'right_wheel', 'odom_frame_id',
    'base_frame_id', 'tf_frame_prefix_enable', 'tf_frame_prefix', 'enable_odom_tf',
    'publish_rate', 'cmd_vel_timeout', 'use_stamped_vel', 'open_loop', 'position_feedback',
)) | frozenset(_AXIS_KEYS)


def convert(params: Mapping[str, Any], controller: str = '', found_by: str = '',
            namespace: str | None = '') -> Conversion:
    """
    Map the parameters of one DDC section to ours.

    Parameters
    ----------
    params : mapping
        The section's parameters, flattened to dotted names.
    controller, found_by : str
        The section's name and how it was found, for the report.
    namespace : str or None
        The controller's namespace ('' = root; None = any): DDC prefixes its frames with it.

    Raises
    ------
    DdcError
        Without ``wheel_separation`` or ``wheel_radius``, or for a value DDC would not accept.

    """
    conv = Conversion(controller, found_by)
    p = dict(params)
    _geometry(p, conv)
    _joints_of(p, conv)
    _frames(p, conv, namespace)
    _node_settings(p, conv)
    for axis in AXES:
        _limits(p, conv, axis, 'velocity')
        _limits(p, conv, axis, 'acceleration')
        _jerk(p, conv, axis)
    _the_rest(p, conv)
    _check_for_the_nodes(conv)
    return conv


def _check_for_the_nodes(conv: Conversion) -> None:
    """Refuse values the nodes would refuse at start, with their own messages."""
    problems = check_values(TERRAIN_PARAMS + ENCODER_INPUT_PARAMS + COMMAND_LIMIT_PARAMS,
                            conv.values)
    if not problems:
        try:
            icr_from_values(conv.values)
        except ValueError as err:
            problems = [str(err)]
    if problems:
        raise DdcError('the converted values would not start the nodes: ' + '; '.join(problems))


def convert_file(path: str | os.PathLike, controller: str | None = None) -> Conversion:
    """Read a controllers file, find its DDC section and convert it (see :func:`convert`)."""
    source = os.fspath(path)
    doc = load_controllers(source)
    try:
        section = find_controller(doc, controller, source)
    except RecursionError:
        raise DdcError(f'{source}: nested too deeply to be a parameter file') from None
    try:
        conversion = convert(section.params, section.name, section.found_by, section.namespace)
    except DdcError as err:
        raise DdcError(f'{source}: controller {section.name!r}: {err}') from None
    return conversion


def _geometry(p: dict, conv: Conversion) -> None:
    separation = read_positive(p, 'wheel_separation', unit=' m')
    radius = read_positive(p, 'wheel_radius', unit=' m')
    multiplier = read_positive(p, 'wheel_separation_multiplier', 1.0)
    both = read_positive(p, 'wheel_radius_multiplier', 1.0)  # ROS 1: one for both sides
    left = read_positive(p, 'left_wheel_radius_multiplier', both)
    right = read_positive(p, 'right_wheel_radius_multiplier', both)
    effective = separation * multiplier
    half = clean(0.5 * effective)
    width = clean(separation if multiplier >= 1.0 else effective)
    conv.values.update({'track_width': width, 'sprocket_radius': clean(radius),
                        'icr.y_left': half, 'icr.y_right': -half, 'icr.x': 0.0,
                        'scale.left': clean(left), 'scale.right': clean(right)})
    m_text = fmt(p['wheel_separation_multiplier']) if 'wheel_separation_multiplier' in p \
        else '1 (default)'
    if multiplier >= 1.0:
        conv.mapped.append((f'wheel_separation = {fmt(separation)}',
                            f'track_width = {fmt(width)}'))
    else:
        conv.narrowed = True
        conv.mapped.append((f'wheel_separation = {fmt(separation)} x multiplier {m_text}',
                            f'track_width = {fmt(width)} (the effective separation)'))
        conv.warnings.append(
            f'wheel_separation_multiplier {m_text} < 1: DDC turns the robot 1/{m_text} = '
            f'{1.0 / multiplier:.3g} times faster than wheel_separation {fmt(separation)} m '
            f'says, as if its tracks were {fmt(clean(effective))} m apart. A tread ICR model '
            f'cannot put the ICRs inside the tracks (chi would be {1.0 / multiplier:.3g} > 1, '
            f'which every node refuses), so track_width = {fmt(width)} m is written with '
            "ideal ICRs: the odometry and the commands are exactly DDC's, but track_width is "
            f'not the measured {fmt(separation)} m. If that is the real distance between the '
            f'track centrelines, the multiplier compensated something else (radius, scale): '
            f'identify_icr on a bag with ground truth finds the real model.')
    conv.mapped.append((
        f'wheel_separation x wheel_separation_multiplier = {fmt(separation)} x {m_text}',
        f'icr.y_left = {fmt(half)}, icr.y_right = {fmt(-half)}, icr.x = 0 '
        f'(chi = {width / effective:.4g}, e = 0)'))
    conv.mapped.append((f'wheel_radius = {fmt(radius)}', f'sprocket_radius = {fmt(radius)}'))
    for side, value in (('left', left), ('right', right)):
        key = f'{side}_wheel_radius_multiplier'
        given = key in p or 'wheel_radius_multiplier' in p
        source = key if key in p or 'wheel_radius_multiplier' not in p \
            else 'wheel_radius_multiplier (ROS 1)'
        conv.mapped.append((f'{source} = {fmt(value)}' + ('' if given else ' (default)'),
                            f'scale.{side} = {fmt(clean(value))}'))


def _joints_of(p: dict, conv: Conversion) -> None:
    found = {}
    for side in ('left', 'right'):
        key = next((k for k in (f'{side}_wheel_names', f'{side}_wheel') if k in p), None)
        if key is None:
            conv.warnings.append(
                f'{side}_wheel_names is not in the section: {side}_joints is not written '
                f"(odometry_node's default is [{side}_sprocket_joint]); set it to the joints "
                'of that side')
            continue
        names = read_joints(key, p[key])
        found[side] = names
        conv.values[f'{side}_joints'] = names
        conv.mapped.append((f'{key} = {fmt(p[key])}', f'{side}_joints = {fmt(names)}'))
        if any('$(' in n for n in names):
            conv.warnings.append(f'{key} contains a launch substitution; edit {side}_joints in '
                                 'the output to the real joint names')
    if len(found) == 2:
        both = sorted(set(found['left']) & set(found['right']))
        if both:
            raise DdcError(f'left and right wheel names both list {", ".join(both)}')
        if len(found['left']) != len(found['right']):
            conv.warnings.append(
                f'{len(found["left"])} left and {len(found["right"])} right wheel names: DDC '
                'refuses different counts; odometry_node averages each side on its own')


def _frames(p: dict, conv: Conversion, namespace: str | None) -> None:
    """Return the frames as DDC publishes them (its ``on_configure`` prefix rule)."""
    odom = read_text('odom_frame_id', p['odom_frame_id']) if 'odom_frame_id' in p else None
    base = read_text('base_frame_id', p['base_frame_id']) if 'base_frame_id' in p else None
    enable = read_bool('tf_frame_prefix_enable', p['tf_frame_prefix_enable']) \
        if 'tf_frame_prefix_enable' in p else True
    explicit = read_text('tf_frame_prefix', p['tf_frame_prefix']).strip('/') \
        if 'tf_frame_prefix' in p else ''
    prefix, why = '', 'no frame prefix'
    if enable and explicit:
        prefix, why = explicit, f'frames prefixed with {explicit}/'
    elif enable and namespace:
        prefix, why = namespace, f"frames prefixed with the section's namespace {namespace}/"
    elif enable and namespace is None:
        conv.warnings.append(
            "DDC prefixes its frames with the controller's namespace (tf_frame_prefix_enable "
            'true, tf_frame_prefix empty) and this section applies in any namespace: the '
            'frames are written without a prefix; in a namespace NS set odom_frame and '
            'base_frame to NS/odom and NS/base_link')
    for key in ('tf_frame_prefix_enable', 'tf_frame_prefix'):
        if key in p:
            conv.mapped.append((f'{key} = {fmt(p[key])}', why))
    if prefix:
        odom, base = odom or 'odom', base or 'base_link'
    for ddc_key, ours, value in (('odom_frame_id', 'odom_frame', odom),
                                 ('base_frame_id', 'base_frame', base)):
        if value is None:
            continue
        full = f'{prefix}/{value}' if prefix else value
        problem = frame_id(full)
        if problem:
            raise DdcError(f'{ddc_key} {problem}')
        conv.values[ours] = full
        given = f'{ddc_key} = {value}' if ddc_key in p else f'{ddc_key} (default {value})'
        conv.mapped.append((given + (f' with prefix {prefix}/' if prefix else ''),
                            f'{ours} = {full}'))


def _node_settings(p: dict, conv: Conversion) -> None:
    if 'enable_odom_tf' in p:
        value = read_bool('enable_odom_tf', p['enable_odom_tf'])
        conv.values['publish_tf'] = value
        conv.mapped.append((f'enable_odom_tf = {fmt(value)}', f'publish_tf = {fmt(value)}'))
    if 'publish_rate' in p:
        rate = read_number('publish_rate', p['publish_rate'])
        if math.isfinite(rate) and rate > 0.0:
            conv.values['publish_rate'] = clean(rate)
            conv.mapped.append((f'publish_rate = {fmt(rate)}', f'publish_rate = {fmt(rate)}'))
        else:
            conv.not_mapped.append((f'publish_rate = {fmt(p["publish_rate"])}',
                                    'not a rate > 0; odometry_node publishes on every encoder '
                                    'message'))
    else:
        conv.not_mapped.append(('publish_rate (not set: DDC default 50 Hz)',
                                'odometry_node publishes on every joint_states message unless '
                                'publish_rate is set'))
    if 'cmd_vel_timeout' in p:
        timeout = read_number('cmd_vel_timeout', p['cmd_vel_timeout'])
        given = f'cmd_vel_timeout = {fmt(p["cmd_vel_timeout"])}'
        if math.isnan(timeout) or timeout < 0.0:
            conv.not_mapped.append((given, 'not a timeout >= 0; cmd_vel_translator keeps its '
                                           'default'))
            conv.warnings.append(f'cmd_vel_timeout {fmt(p["cmd_vel_timeout"])} is not a '
                                 "timeout >= 0: cmd_timeout not written (cmd_vel_translator's "
                                 'default 0.5 s applies)')
        elif timeout == 0.0 or math.isinf(timeout):
            conv.values['cmd_timeout'] = 0.0
            conv.mapped.append((given, 'cmd_timeout = 0 (disabled: commands never go stale)'))
        else:
            conv.values['cmd_timeout'] = clean(timeout)
            conv.mapped.append((given, f'cmd_timeout = {fmt(timeout)}'))
            if timeout > 60.0:
                conv.warnings.append(
                    f'cmd_vel_timeout {fmt(timeout)} s is over a minute: early ROS 2 DDC read '
                    f'it in milliseconds; if you meant {fmt(timeout / 1000.0)} s, edit '
                    'cmd_timeout in the output')
    if 'use_stamped_vel' in p:
        value = read_bool('use_stamped_vel', p['use_stamped_vel'])
        conv.values['use_stamped'] = value
        conv.mapped.append((f'use_stamped_vel = {fmt(value)}',
                            f'use_stamped = {fmt(value)} (delete it to let cmd_vel_translator '
                            "follow the publishers' message type)"))
    else:
        conv.not_mapped.append((
            'use_stamped_vel (not set: DDC subscribes to TwistStamped)',
            'cmd_vel_translator follows the message type of the publishers on cmd_vel; '
            'use_stamped: true forces TwistStamped'))
    if p.get('open_loop') is not None:
        value = read_bool('open_loop', p['open_loop'])
        conv.not_mapped.append((f'open_loop = {fmt(value)}', (
            'odometry_node always integrates the encoders (= open_loop false)' if not value
            else 'DDC integrated its commands; odometry_node integrates the encoders')))
        if value:
            conv.warnings.append('open_loop is true: DDC computed its odometry from the '
                                 'commands; odometry_node uses the joint states, so its '
                                 'odometry will differ (it follows what the tracks did)')
    if p.get('position_feedback') is not None:
        value = read_bool('position_feedback', p['position_feedback'])
        conv.not_mapped.append((f'position_feedback = {fmt(value)}', (
            'odometry_node uses joint positions when joint_states has them for every joint '
            '(= position_feedback true), velocities otherwise' if value else
            'odometry_node uses joint positions when joint_states has them for every joint, '
            'and velocities only otherwise; nothing forces velocities')))


def _axis_values(p: dict, axis: str, names) -> dict[str, float]:
    return {name: read_number(f'{axis}.{name}', p[f'{axis}.{name}'])
            for name in names if f'{axis}.{name}' in p}


# Per kind: the has_* switch and every DDC bound with the direction it limits. DDC's limits
# are signed bounds (min_velocity < 0 limits reversing; min_acceleration < 0 limits slowing
# down forwards and speeding up backwards); cmd_vel_translator's are one magnitude for both
# directions. ``sign`` turns the bound into that magnitude; None: take the absolute value
# (the Jazzy deceleration and reverse names, whose sign conventions changed between
# releases).
_BOUNDS = {
    'velocity': ('has_velocity_limits', (('max_velocity', 1.0), ('min_velocity', -1.0))),
    'acceleration': ('has_acceleration_limits', (
        ('max_acceleration', 1.0), ('min_acceleration', -1.0), ('max_deceleration', None),
        ('max_acceleration_reverse', None), ('max_deceleration_reverse', None))),
}
_UNITS = {('linear.x', 'velocity'): 'm/s', ('linear.x', 'acceleration'): 'm/s^2',
          ('angular.z', 'velocity'): 'rad/s', ('angular.z', 'acceleration'): 'rad/s^2'}


def _limits(p: dict, conv: Conversion, axis: str, kind: str) -> None:
    """Return one of our limits from DDC's bounds of one axis: the tighter of its active bounds."""
    switch, bounds = _BOUNDS[kind]
    has_key = f'{axis}.{switch}'
    names = [name for name, _ in bounds]
    present = [k for k in [has_key] + [f'{axis}.{n}' for n in names] if k in p]
    if not present:
        return
    ours = f'{axis}.max_{kind}'
    unit = _UNITS[axis, kind]
    given = ', '.join(f'{k} = {fmt(p[k])}' for k in present)
    enabled = read_bool(has_key, p[has_key]) if has_key in p else None
    if enabled is False:
        conv.values[ours] = 0.0
        conv.mapped.append((given, f'{ours} = 0 (no limit: {switch} is false)'))
        return
    values = _axis_values(p, axis, names)
    magnitudes = []
    for name, sign in bounds:
        value = values.get(name, math.nan)
        if math.isnan(value):
            continue
        magnitude = abs(value) if sign is None else sign * value
        if magnitude > 0.0:
            magnitudes.append((magnitude, name))
        elif enabled:
            conv.warnings.append(
                f'{axis}.{name} = {fmt(value)}: DDC allows no {kind} in that direction; '
                f"cmd_vel_translator's {kind} limits are one magnitude for both directions and "
                f'cannot forbid one, so {axis}.{name} is not applied')
        else:
            conv.warnings.append(
                f"{axis}.{name} = {fmt(value)} without {switch}: Humble's DDC ignores it, "
                f"Jazzy's applies it; cmd_vel_translator cannot apply a limit of 0 (0 means "
                f'none), so it is not applied')
    if enabled and math.isnan(values.get('max_' + kind, math.nan)):
        conv.warnings.append(f'{has_key} is true but {axis}.max_{kind} is not set: DDC refuses '
                             'that configuration')
    if not magnitudes:
        conv.values[ours] = 0.0
        conv.mapped.append((given, f'{ours} = 0 (no limit)'))
        return
    limit, name = min(magnitudes)
    conv.values[ours] = clean(limit)
    conv.mapped.append((given, f'{ours} = {fmt(limit)}'))
    if any(m > limit * (1.0 + 1e-12) for m, _ in magnitudes):
        bounds_text = ', '.join(f'{axis}.{n} = {fmt(values[n])}' for _, n in magnitudes)
        what = 'speeds up and slows down' if kind == 'acceleration' else 'moves'
        conv.warnings.append(
            f'DDC bounds the {axis} {kind} with different values ({bounds_text}); '
            f"cmd_vel_translator's {ours} is one magnitude for both directions"
            + (' and for slowing down' if kind == 'acceleration' else '')
            + f', so the tightest, {fmt(limit)} {unit}, is written: the robot {what} no '
              f'faster than that in any direction')


def _jerk(p: dict, conv: Conversion, axis: str) -> None:
    keys = [f'{axis}.{n}' for n in ('has_jerk_limits', 'max_jerk', 'min_jerk')
            if f'{axis}.{n}' in p]
    if not keys:
        return
    given = ', '.join(f'{k} = {fmt(p[k])}' for k in keys)
    has_key = f'{axis}.has_jerk_limits'
    enabled = read_bool(has_key, p[has_key]) if has_key in p else None
    values = _axis_values(p, axis, ('max_jerk', 'min_jerk'))
    active = enabled is not False and any(math.isfinite(v) and v != 0.0 for v in values.values())
    if active:
        conv.not_mapped.append((given, 'cmd_vel_translator has no jerk limit'))
        conv.warnings.append(f'DDC limits the {axis} jerk ({given}); cmd_vel_translator does '
                             'not: its acceleration ramps start and stop at once')
    else:
        conv.not_mapped.append((given, 'inactive in DDC; cmd_vel_translator has no jerk limit '
                                       'either'))


def _the_rest(p: dict, conv: Conversion) -> None:
    """Say what became of the other keys; refuse a misspelling of a key that is mapped."""
    known = sorted(_HANDLED | set(_NO_COUNTERPART))
    misspelt = []
    for key, value in p.items():
        if key in _HANDLED:
            continue
        reason = _NO_COUNTERPART.get(key)
        if reason is None:
            reason = ('not a ROS 2 diff_drive_controller parameter (a ROS 1, vendor or '
                      'misspelt key); DDC ignores it too')
            close = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
            if close:
                reason += f'; did you mean {close[0]!r}?'
                if close[0] in _HANDLED and close[0] not in p:
                    misspelt.append(f'{key!r} (did you mean {close[0]!r}?)')
        conv.not_mapped.append((f'{key} = {fmt(value)}', reason))
    if misspelt:
        raise DdcError(
            f'{", ".join(misspelt)}: not a diff_drive_controller parameter, so DDC ignored '
            'it and the conversion would too, taking the default of the parameter it '
            'resembles; correct the spelling in the file (DDC will then apply it as well)')
