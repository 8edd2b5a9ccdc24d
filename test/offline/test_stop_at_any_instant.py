"""
A SIGINT or SIGTERM at any instant of an offline tool leaves nothing new behind (issue 20).

Every tool that writes runs as its console script in a directory of its own that holds a
file of the user's and, for most, an output that ``--force`` replaces. It runs once
unsignalled (:data:`PARALLEL` runs at once, as the signalled ones go), which measures how
long it lives on this machine now and what it writes; then it is signalled :data:`INSTANTS`
times: at instants spread evenly (with jitter) over that life, just after its first output
(a temporary file) appears, where staging and writing begin, and just after its temporary
files have gone again, where the commit has been. SIGINT and SIGTERM alternate; every
fourth run gets a second signal soon after the first. Each run must end

- with status 0 (it finished first, or the signal came after the run's end), or with the
  documented status of a signal sent (130, 143) and one line ``PROG: error: ...`` last on
  stderr; never a traceback, never death by the signal's default action;
- with the directory as it was (the user's files byte for byte, no temporary file), or,
  once the run has committed, with exactly the outputs of the unsignalled run and the
  user's files untouched. Never a subset of them.

Instants are measured from the moment the tool's process has taken SIGTERM (read from
/proc), except the ``early`` ones: at once, or at a random instant of the first 1.5 s after
the process started, waiting for nothing. One that comes before the package's first line
(read from /proc just before the signal) lands in the interpreter's own start-up and may
take Python's course (docs/testing.md): death by the signal, or Python's
KeyboardInterrupt traceback with no frame of the package, and nothing written.
"""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import hashlib
import json
import os
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import time

from helpers.setup_info import console_scripts, ROOT
from helpers.stops import python_course
import pytest
from tracked_kinematics import TOOL_EXECUTABLES
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.outputs import PROBE_MARK

BIN = Path(sys.executable).parent
SCALE = max(1, int(os.environ.get('TRACKED_KINEMATICS_STOP_SCALE', '1')))
"""``make stress`` sets TRACKED_KINEMATICS_STOP_SCALE=4: four times the instants."""
FULL = ('spread',) * 3 + ('first output',) + ('commit',) + ('early',) * 2
"""One full set: 3 instants spread over the tool's life, 1 at its first output, 1 at its
commit, 2 early: at once, and in its first :data:`EARLY` s."""
KINDS = FULL * SCALE if SCALE > 1 else ('spread',) * 2 + ('first output', 'commit', 'early')
"""The suite's share: 2 instants spread over the tool's life (the first half's always lands
in it), one of each other kind (``make stress``, at scale 4, runs four full sets: 28 per
tool)."""
EARLY = 1.5
"""Seconds after the process started: the span of the early instants."""
INSTANTS = len(KINDS)
PARALLEL = 2
DEADLINE = 300.0
"""Seconds: generous bounds of every wait (a loaded 2-core machine)."""
STOPS = {signal.SIGINT: (130, 'interrupted'), signal.SIGTERM: (143, 'terminated by SIGTERM')}
USER_FILE = 'notes.txt'
OLD = b"the user's old version\n"


@pytest.fixture(scope='module')
def inputs(tmp_path_factory):
    """Write a calibration bag of the PackBot (40 s, mcap) and its true model (terrain)."""
    directory = tmp_path_factory.mktemp('inputs')
    sim = simulate_bag(directory / 'cal', 'packbot', duration=40.0, seed=3, storage='mcap')
    return {'bag': str(sim.bag), 'truth': str(sim.truth),
            'controllers': str(ROOT / 'test' / 'data' / 'ddc' / 'husky_style_controllers.yaml')}


def tool_argv(name, inputs):
    """Return the command line of a tool (small inputs), outputs in the working directory."""
    bag, truth = inputs['bag'], inputs['truth']
    return {
        'simulate_bag': ['run', '--vehicle', 'packbot', '--duration', '5', '--truth',
                         'truth.yaml', '--force'],
        'identify_icr': [bag, '--ground-truth-topic', '/ground_truth/pose', '--sprocket-radius',
                         '0.085', '--track-width', '0.4', '--holdout', '0', '--output',
                         'fit.yaml', '--report', 'fit.json', '--plot', 'fit.png', '--force'],
        'identify_drivetrain': [bag, '--sprocket-radius', '0.085', '--output', 'dt.yaml',
                                '--report', 'dt.json', '--force'],
        'evaluate_model': [bag, '--ground-truth-topic', '/ground_truth/pose', '--params', truth,
                           '--report', 'ev.json', '--tum', 'tum'],
        'icr_map': ['packbot', '--n', '5', '--csv', 'map.csv', '--output', 'map.yaml',
                    '--force'],
        'plan_trajectory': ['--canonical', 'straight', '--vehicle', 'packbot', '--params', truth,
                            '--csv', 'plan.csv', '--bag', 'plan'],
        'convert_diff_drive_params': [inputs['controllers'], '--output', 'terrain.yaml',
                                      '--force'],
        'tracked_kinematics_demo': ['--output', 'demo', '--paths', '1', '--duration', '15',
                                    '--path-duration', '1', '--vehicle', 'packbot',
                                    '--storage', 'sqlite3'],
    }[name]


REPLACED = {'simulate_bag': 'truth.yaml', 'identify_icr': 'fit.yaml',
            'identify_drivetrain': 'dt.yaml', 'icr_map': 'map.csv',
            'convert_diff_drive_params': 'terrain.yaml'}
"""The output of each tool that exists before the run, the user's, replaced with --force."""


def prepare(work: Path, name: str) -> dict:
    """Make a working directory with the user's files; return its state."""
    work.mkdir()
    (work / USER_FILE).write_bytes(os.urandom(64))
    if name in REPLACED:
        (work / REPLACED[name]).write_bytes(OLD)
    return state(work)


def state(directory: Path) -> dict:
    """Every entry under ``directory`` (hidden ones too): 'dir', or a file's sha256."""
    found = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs:
            found[os.path.relpath(os.path.join(root, name), directory)] = 'dir'
        for name in files:
            path = os.path.join(root, name)
            with open(path, 'rb') as stream:
                found[os.path.relpath(path, directory)] = hashlib.sha256(
                    stream.read()).hexdigest()
    return found


def takes_sigterm(pid: int) -> bool:
    """Whether the process catches SIGTERM and SIGHUP: the package is running in it."""
    try:
        with open(f'/proc/{pid}/status') as stream:
            caught = next(int(line.split()[1], 16) for line in stream
                          if line.startswith('SigCgt:'))
    except (OSError, StopIteration):
        return False
    return all(caught >> (s - 1) & 1 for s in (signal.SIGTERM, signal.SIGHUP))


def wait_for(condition, process) -> bool:
    """Poll ``condition`` until it holds (True) or the process ends (False)."""
    deadline = time.monotonic() + DEADLINE
    while time.monotonic() < deadline:
        if condition():
            return True
        if process.poll() is not None:
            return False
        time.sleep(0.002)
    raise AssertionError(f'timed out after {DEADLINE} s')


@dataclass
class Result:
    """How one run ended."""

    status: int
    stderr: str
    life: float
    """Seconds from the package's start in the process to the exit."""
    ready: bool
    """The package took SIGTERM before the process ended."""
    final: dict = None
    """:func:`state` of the working directory after the run."""
    before_package: bool = False
    """The (first) signal was sent before the process took SIGTERM."""


def run_tool(name, argv, work, plan=None) -> Result:
    """
    Run the console script ``name`` in ``work``; signal it as ``plan`` says.

    ``plan``: ``(when, signum, second)``; ``when`` is seconds after the package has taken
    SIGTERM, or ``('first output', seconds)`` after the first new entry in ``work``, or
    ``('commit', seconds)`` after its temporary files have gone again, or ``('early',
    seconds)`` after the process started, waiting for nothing; ``second`` is None or
    ``(seconds after, signum)``. The start check's file (:data:`PROBE_MARK`) is neither an
    output nor a temporary file here: it comes and goes before any work.
    """
    before = set(os.listdir(work))

    def temporary():
        return any('.tmp-' in n and PROBE_MARK not in n
                   for _, dirs, files in os.walk(work) for n in dirs + files)

    def new_entries():
        return {n for n in set(os.listdir(work)) - before if PROBE_MARK not in n}
    before_package = False
    with open(work.parent / f'{work.name}.stderr', 'w+') as err:
        process = subprocess.Popen([str(BIN / name), *argv], cwd=work,
                                   stdout=subprocess.DEVNULL, stderr=err)
        try:
            if plan is not None and isinstance(plan[0], tuple) and plan[0][0] == 'early':
                time.sleep(plan[0][1])
                before_package = not takes_sigterm(process.pid)
                process.send_signal(plan[1])
                if plan[2] is not None:
                    time.sleep(plan[2][0])
                    process.send_signal(plan[2][1])
                plan = None
            ready = wait_for(lambda: takes_sigterm(process.pid), process)
            start = time.monotonic()
            if plan is not None and ready:
                when, signum, second = plan
                if isinstance(when, tuple):
                    wrote = wait_for(new_entries, process)
                    if when[0] == 'commit':
                        wrote = wrote and wait_for(temporary, process) and wait_for(
                            lambda: not temporary(), process)
                    time.sleep(when[1])
                else:
                    wrote = True
                    time.sleep(when)
                if wrote:
                    process.send_signal(signum)
                    if second is not None:
                        time.sleep(second[0])
                        process.send_signal(second[1])
            status = process.wait(timeout=DEADLINE)
            life = time.monotonic() - start
        finally:
            process.kill()
            process.wait()
        err.seek(0)
        return Result(status, err.read(), life, ready, state(work), before_package)


def plans(rng, life):
    """Return the :data:`INSTANTS` signal plans of a tool that lives ``life`` seconds."""
    spread = KINDS.count('spread')
    out = []
    spread_index = early_index = 0
    for k, kind in enumerate(KINDS):
        signum = (signal.SIGINT, signal.SIGTERM)[k % 2]
        if kind == 'spread':  # the i-th of them in the i-th slice of its life
            when = 1.1 * life * (spread_index + rng.random()) / spread
            spread_index += 1
        elif kind == 'early':  # at once, then at random in the first EARLY s, in turn
            when = (kind, 0.0 if early_index % 2 == 0 else rng.uniform(0.0, EARLY))
            early_index += 1
        else:
            when = (kind, rng.uniform(0.0, 0.02))
        second = None
        if k % 4 == 3:
            second = (rng.uniform(0.0, 0.05), rng.choice(tuple(STOPS)))
        out.append((when, signum, second))
    return out


def describe(plan) -> str:
    when, signum, second = plan
    text = (f'{when[1] * 1000:.0f} ms after its {when[0]}' if isinstance(when, tuple)
            else f'{when:.3f} s after start')
    text += f', {signal.Signals(signum).name}'
    if second:
        text += f', then {signal.Signals(second[1]).name} {second[0] * 1000:.0f} ms later'
    return text


def classify(name, plan, result: Result, before, complete, baseline_err):
    """Check one signalled run; 'finished', 'nothing left', 'committed' or 'before us'."""
    status, err, final = result.status, result.stderr, result.final
    what = f'{name}, signal {describe(plan)}: exit {status}, stderr {err!r}'
    if result.before_package and python_course(plan[1], status, err):
        assert final == before, what   # the interpreter's start-up: nothing written
        return 'before us'
    assert 'Traceback' not in err and 'Exception ignored' not in err, what
    sent = {plan[1]} | ({plan[2][1]} if plan[2] else set())
    if status == 0:
        assert err == baseline_err, what
        assert outputs_complete(final, before, complete), (what, final)
        return 'finished'
    allowed = {STOPS[s][0]: STOPS[s][1] for s in sent}
    assert status in allowed, what
    lines = err.splitlines()
    assert lines and lines[-1] == f'{name}: error: {allowed[status]}', what
    assert not any('error:' in line for line in lines[:-1]), what
    if final == before:
        return 'nothing left'
    assert outputs_complete(final, before, complete), (
        what, sorted(set(final) - set(before)), sorted(set(before) - set(final)))
    return 'committed'


def outputs_complete(final: dict, before: dict, complete: set) -> bool:
    """Exactly the unsignalled run's entries, the user's file as it was, replaced ones new."""
    if set(final) != complete:
        return False
    return all(final[path] != digest if path in REPLACED.values() else final[path] == digest
               for path, digest in before.items())


#: The tools make test signals at every instant: none (identify_icr's three signals mid-write
#: are in test_identify_cli); make stress signals every tool, the fit, the scoring and the
#: demo included (docs/testing.md).
SUITE_TOOLS = ()


@pytest.mark.parametrize('name', [
    name if name in SUITE_TOOLS else pytest.param(name, marks=pytest.mark.long)
    for name in TOOL_EXECUTABLES])
def test_a_signal_at_any_instant_leaves_the_outputs_whole_or_absent(name, inputs, tmp_path):
    argv = tool_argv(name, inputs)
    before = {}

    def unsignalled(k):
        work = tmp_path / f'baseline{k}'
        before[k] = prepare(work, name)
        return run_tool(name, argv, work)

    with ThreadPoolExecutor(PARALLEL) as pool:
        baselines = list(pool.map(unsignalled, range(PARALLEL)))
    for result in baselines:
        assert result.status == 0 and result.ready, result.stderr
        assert 'Traceback' not in result.stderr
    baseline_err, written = baselines[0].stderr, baselines[0].final
    before = before[0]
    life = sorted(r.life for r in baselines)[len(baselines) // 2]
    assert all(r.stderr == baseline_err and set(r.final) == set(written) for r in baselines)
    complete = set(written)
    assert written != before and outputs_complete(written, before, complete)
    assert not any('.tmp-' in path for path in complete), complete

    rng = random.Random(f'{name} {INSTANTS}')
    runs = plans(rng, life)

    def one(k):
        work = tmp_path / f'run{k:02d}'
        start = prepare(work, name)
        result = run_tool(name, argv, work, runs[k])
        shutil.rmtree(work)
        return start, result

    with ThreadPoolExecutor(PARALLEL) as pool:
        results = list(pool.map(one, range(INSTANTS)))
    counts = {'finished': 0, 'nothing left': 0, 'committed': 0, 'before us': 0}
    for k, (start, result) in enumerate(results):
        counts[classify(name, runs[k], result, start, complete, baseline_err)] += 1
    print(f'{name}: life {life:.2f} s; {json.dumps(counts)}')
    # Not vacuous: the signals did stop runs (most land before the end of a run).
    assert counts['nothing left'] + counts['committed'] > 0, counts


def test_the_tools_that_take_signals_at_start_are_the_offline_console_scripts():
    offline = {name for name, target in console_scripts().items()
               if target.startswith('tracked_kinematics.offline.')}
    assert set(TOOL_EXECUTABLES) == offline
