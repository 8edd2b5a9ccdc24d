"""
Every console script takes SIGINT and SIGTERM at the package's first line (issue 27 item 7).

A console script's wrapper imports ``tracked_kinematics.<ring>.<module>``: the package's
``__init__`` runs first. Here a fresh interpreter named after each script imports the
package's ``__init__`` alone and reports its handlers and what it imported; then each
script is started and signalled at the instant it has taken the signals.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from helpers.setup_info import console_scripts
import pytest
import tracked_kinematics

BIN = Path(sys.executable).parent
HEAVY = ('numpy', 'scipy', 'rclpy', 'rosbags', 'yaml', 'matplotlib')
PROBE = r"""
import json, signal, sys
sys.argv[0] = sys.argv[1]
import tracked_kinematics
names = {}
for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    handler = signal.getsignal(sig)
    names[sig.name] = (f'{handler.__module__}.{handler.__qualname__}' if callable(handler)
                       else signal.Handlers(handler).name)
print(json.dumps({'handlers': names, 'modules': sorted(sys.modules)}))
"""


def handlers_after_the_first_import(name):
    """Import only the package's ``__init__`` in a process called ``name``; what it did."""
    result = subprocess.run([sys.executable, '-c', PROBE, name], capture_output=True,
                            text=True, check=True)
    return json.loads(result.stdout)


def inherited(sig):
    """Return what a child of this process has of ``sig`` at its start (ignored stays so)."""
    return 'SIG_IGN' if signal.getsignal(sig) == signal.SIG_IGN else 'SIG_DFL'


def kind(target):
    """'node' (ros/ and apps/) or 'tool' (offline/) of a console script's entry point."""
    return 'tool' if target.startswith('tracked_kinematics.offline.') else 'node'


@pytest.mark.parametrize('name, target', sorted(console_scripts().items()))
def test_the_package_init_takes_the_signals_of_every_console_script(name, target):
    expected = {'node': tracked_kinematics.NODE_EXECUTABLES,
                'tool': tracked_kinematics.TOOL_EXECUTABLES}[kind(target)]
    assert name in expected
    found = handlers_after_the_first_import(name)
    handlers = found['handlers']
    if kind(target) == 'node':
        assert handlers['SIGINT'] == handlers['SIGTERM'] == 'tracked_kinematics.exit_quietly'
        # SIGHUP is left as it came (ignored under nohup, as a suite started so has it).
        assert handlers['SIGHUP'] == inherited(signal.SIGHUP)
    else:
        assert set(handlers.values()) == {'tracked_kinematics.offline.signals._on_signal'}
    # Cheap: nothing heavy, nothing of the package beyond its handler's module.
    assert not [m for m in found['modules'] if m.split('.')[0] in HEAVY]
    ours = {m for m in found['modules'] if m.startswith('tracked_kinematics')}
    assert ours <= {'tracked_kinematics', 'tracked_kinematics.offline',
                    'tracked_kinematics.offline.signals'}


def test_any_other_process_keeps_its_handlers():
    handlers = handlers_after_the_first_import('python3')['handlers']
    assert handlers == {'SIGINT': '_signal.default_int_handler',
                        'SIGTERM': inherited(signal.SIGTERM), 'SIGHUP': inherited(signal.SIGHUP)}


def catches(pid, signum):
    try:
        with open(f'/proc/{pid}/status') as status:
            for line in status:
                if line.startswith('SigCgt:'):
                    return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    except OSError:
        pass
    return False


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize('name', ['calibration_drive', 'odometry_node', 'identify_icr'])
def test_a_signal_as_soon_as_the_package_has_run(tmp_path, name, signum):
    # The first instant the package can answer for: a node exits 0 quietly, a tool with the
    # signal's status and one line. calibration_drive used to import its offline code
    # (scipy, 1.1 s) before it took signals, and died of them or printed a traceback.
    argv = [str(BIN / name)] + (['--ros-args', '-p', f'output:={tmp_path}/fit.yaml']
                                if name != 'identify_icr' else ['bag', '--output', 'x.yaml'])
    process = subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               env={**os.environ, 'PYTHONUNBUFFERED': '1'})
    deadline = time.monotonic() + 60.0
    while not catches(process.pid, signal.SIGTERM) and time.monotonic() < deadline:
        assert process.poll() is None
    process.send_signal(signum)
    out, err = process.communicate(timeout=60.0)
    if name == 'identify_icr':
        status = {signal.SIGINT: 130, signal.SIGTERM: 143}[signum]
        reason = 'interrupted' if signum == signal.SIGINT else 'terminated by SIGTERM'
        assert (process.returncode, out, err) == (status, '', f'{name}: error: {reason}\n')
    else:
        assert (process.returncode, out, err) == (0, '', '')
    assert os.listdir(tmp_path) == []
