"""
docs/calibrate-in-five-minutes.md's simulator section, run as a user would (issue 31).

Every bash block of the section, copied from the page, in a fresh directory, with the venv's
console scripts on the PATH (the page says to activate the venv): the one-line commands
run to the end, the three nodes run in the background, and the last command (the deadman)
ends when the drive is done. It must leave a terrain file.
"""

import os
from pathlib import Path
import re
import signal
import subprocess
import sys

from helpers.setup_info import ROOT
import pytest
from tracked_kinematics.params import read_params_file

PAGE = ROOT / 'docs' / 'calibrate-in-five-minutes.md'
BIN = Path(sys.executable).parent
WALK_LIMIT = 150
"""s: longest the page's walk may take before it is called stuck."""
FENCED = re.compile(r'^```bash\n(.*?)^```', re.S | re.M)


def simulator_commands():
    """Return the commands of the page's simulator section, in order."""
    text = PAGE.read_text()
    section = text[text.index('## In the simulator'):text.index('\n## ', text.index(
        '## In the simulator') + 1)]
    return [block.replace('\\\n', ' ').strip() for block in FENCED.findall(section)]


def test_the_section_is_what_the_walk_runs():
    commands = simulator_commands()
    assert [c.split()[0] for c in commands] == [
        'printf', 'tracked_simulator', 'cmd_vel_translator', 'calibration_drive',
        'calibration_deadman']
    assert all('ros2' not in c for c in commands)   # the venv has no ros2 CLI


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.long   # 24 s of CPU; test_calibration_drive drives the same loop in make test
def test_the_simulator_walk_ends_with_a_terrain_file(tmp_path):
    setup, *nodes, deadman = simulator_commands()
    env = {**os.environ, 'PATH': f'{BIN}{os.pathsep}{os.environ["PATH"]}',
           'PYTHONUNBUFFERED': '1'}
    subprocess.run(setup, shell=True, check=True, cwd=tmp_path, env=env)
    running = []

    def start(command, name):
        log = open(tmp_path / f'{name}.log', 'w')
        # A session of its own: the shell and the script it runs are stopped together.
        running.append((subprocess.Popen(command, shell=True, cwd=tmp_path, env=env,
                                         stdout=log, stderr=subprocess.STDOUT,
                                         start_new_session=True), log))
        return running[-1][0]

    def logs():
        return '\n'.join((tmp_path / f'node{k}.log').read_text()[-3000:]
                         for k in range(len(nodes)))
    try:
        for k, command in enumerate(nodes):
            start(command, f'node{k}')
        held = start(deadman, 'deadman')
        try:
            # 20 s of wall time on a quiet machine: a walk still going after WALK_LIMIT is stuck.
            status = held.wait(WALK_LIMIT)
        except subprocess.TimeoutExpired:
            status = None
        shown = (tmp_path / 'deadman.log').read_text()
        assert status == 0, f'the walk ended with {status}:\n{shown}\n{logs()}'
        assert 'calibration drive done (exit status 0)' in shown, shown + logs()
        assert running[2][0].wait(60) == 0, logs()   # the drive has exited by itself
    finally:
        for process, log in running:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
                try:
                    process.wait(20)
                except subprocess.TimeoutExpired:
                    os.killpg(process.pid, signal.SIGKILL)
                    process.wait()
            log.close()
    values = read_params_file(tmp_path / 'hard_floor.yaml')
    assert 0.4 < values['icr.y_left'] - values['icr.y_right'] < 1.2
    assert (tmp_path / 'hard_floor.json').is_file()
    assert (tmp_path / 'hard_floor_drive' / 'metadata.yaml').is_file()
