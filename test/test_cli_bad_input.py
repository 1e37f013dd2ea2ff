# Copyright 2026 polarization_compass developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Every `polarization-compass` command fed bad input exits 2 with one clear line.

The line goes to stderr, nothing to stdout, exit status 2 means a user error; never a traceback and
never the "internal error" path (exit 70).

Most cases run in-process through ``polarization_compass.cli.main``; a few run the real console
entry point in a subprocess to see exactly what a user sees. Cases of the ``sun`` command already
in test/test_solar.py (latitude 91, NaN latitude, unparsable time, unparsable number) are not
repeated. Commands land over time: the generic tests at the end run over every command that is
registered.
"""

import json
import os
import subprocess
import sys

import numpy as np
from polarization_compass.cli import build_parser, main
import pytest

GOOD_TIME = '2024-01-01T00:00:00Z'


def run(argv, capsys):
    """
    Run one in-process CLI call and return (exit status, stdout, stderr).

    (exit status, stdout, stderr) of one in-process CLI call; argparse's SystemExit is an exit
    status.
    """
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def assert_user_error(rc, out, err, *words):
    assert 'Traceback' not in err and 'internal error' not in err, err
    assert rc == 2, (rc, err)
    assert out == ''
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert 'error' in lines[0]
    for w in words:
        assert w.lower() in lines[0].lower(), (w, lines[0])


@pytest.fixture
def files(tmp_path):
    """Bad input files of every kind, by name."""
    f = {}
    f['missing'] = tmp_path / 'nope.yaml'
    f['directory'] = tmp_path / 'adir'
    f['directory'].mkdir()
    f['binary'] = tmp_path / 'binary.yaml'
    f['binary'].write_bytes(b'\x00\xff\xfe\x80 not text')
    f['python_tag'] = tmp_path / 'evil.yaml'
    f['python_tag'].write_text(
        'name: !!python/object/apply:os.system ["touch %s"]\n' % (tmp_path / 'PWNED')
    )
    f['not_mapping'] = tmp_path / 'list.yaml'
    f['not_mapping'].write_text('[1, 2, 3]\n')
    f['bad_yaml'] = tmp_path / 'bad.yaml'
    f['bad_yaml'].write_text('camera: {width_px: 3\n')
    f['bad_value'] = tmp_path / 'value.yaml'
    f['bad_value'].write_text('camera: {width_px: 0}\n')
    f['a_file'] = tmp_path / 'plain.txt'
    f['a_file'].write_text('x')
    return f


# --------------------------------------------------------------------------------------------
# render
# --------------------------------------------------------------------------------------------
RENDER_BAD_ARGS = [
    (['--yaw', 'nan'], '--yaw'),
    (['--yaw', 'inf'], '--yaw'),
    (['--yaw', '1e9'], '--yaw'),
    (['--pitch', '90.0001'], '--pitch'),
    (['--pitch', '-inf'], '--pitch'),
    (['--roll', '-180.5'], '--roll'),
    (['--sun-altitude', '30'], 'together'),
    (['--sun-azimuth', '30'], 'together'),
    (['--sun-altitude', '91', '--sun-azimuth', '0'], '--sun-altitude'),
    (['--sun-altitude', '30', '--sun-azimuth', 'nan'], '--sun-azimuth'),
    (['--stride', '0'], 'stride'),
    (['--stride', '-3'], 'stride'),
    (['--stride', '100000'], 'stride'),
    (['--time', 'yesterday'], 'ISO 8601'),
    (['--time', '2023-02-29T00:00:00Z'], 'ISO 8601'),
    (['--time', '9999-06-01T00:00:00Z'], 'years'),
    (['--yaw', 'north'], '--yaw'),
    (['--stride', '1.5'], '--stride'),
    (['--frobnicate'], 'unrecognized'),
]


@pytest.mark.parametrize('argv, words', RENDER_BAD_ARGS)
def test_render_bad_arguments(argv, words, tmp_path, capsys):
    rc, out, err = run(
        ['render', '--stride', '64', '--out', str(tmp_path / 'f.npz')] + argv, capsys
    )
    assert_user_error(rc, out, err, words)
    assert not (tmp_path / 'f.npz').exists()


def test_render_without_out_is_a_usage_error(capsys):
    assert_user_error(*run(['render'], capsys), '--out')


@pytest.mark.parametrize(
    'kind, words',
    [
        ('missing', 'does not exist'),
        ('directory', ''),
        ('not_mapping', 'mapping'),
        ('bad_value', 'width_px'),
        ('binary', ''),
        ('python_tag', 'YAML'),
        ('bad_yaml', 'YAML'),
    ],
)
def test_render_bad_scene_files(files, kind, words, tmp_path, capsys):
    rc, out, err = run(
        ['render', '--scene', str(files[kind]), '--out', str(tmp_path / 'f.npz')], capsys
    )
    assert_user_error(rc, out, err, words)
    assert not (tmp_path / 'PWNED').exists()


@pytest.mark.parametrize('kind, words', [('python_tag', 'python/object'), ('bad_yaml', 'YAML')])
def test_render_bad_yaml_is_refused_with_exit_2_and_never_executed(
    files, kind, words, tmp_path, capsys
):
    """The exit status and the refusal (independent of the message-length bug above)."""
    rc, out, err = run(
        ['render', '--scene', str(files[kind]), '--out', str(tmp_path / 'f.npz')], capsys
    )
    assert rc == 2 and out == '' and 'Traceback' not in err and words in err
    assert not (tmp_path / 'PWNED').exists()


@pytest.mark.parametrize(
    'where, words',
    [
        ('plain.txt', '.npz'),
        ('adir.npz', 'directory'),
        ('plain.txt/f.npz', 'directory'),
    ],
)
def test_render_bad_output_paths(files, where, words, tmp_path, capsys):
    out_path = tmp_path / where
    if where == 'adir.npz':
        out_path.mkdir()
    assert_user_error(*run(['render', '--stride', '64', '--out', str(out_path)], capsys), words)


def test_render_png_dir_that_is_a_file(files, tmp_path, capsys):
    assert_user_error(
        *run(
            [
                'render',
                '--stride',
                '64',
                '--out',
                str(tmp_path / 'f.npz'),
                '--png',
                str(files['a_file']),
            ],
            capsys,
        )
    )


@pytest.mark.parametrize(
    'argv',
    [
        ['--yaw', '-180'],
        ['--yaw', '180'],
        ['--yaw', '540'],
        ['--pitch', '90'],
        ['--pitch', '-90'],
        ['--roll', '180'],
        ['--sun-altitude', '90', '--sun-azimuth', '0'],
        ['--sun-altitude', '-90', '--sun-azimuth', '720'],
        ['--time', '2024-02-29T23:59:59.999999Z'],
    ],
)
def test_render_edge_values_are_accepted_and_give_finite_frames(argv, tmp_path, capsys):
    """
    The edges of every documented range are valid input.

    Each gives exit 0, a finite frame and psi in (-180, 180].
    """
    from polarization_compass.frame_io import load_frame_npz

    rc, out, err = run(
        ['render', '--stride', '64', '--out', str(tmp_path / 'f.npz')] + argv, capsys
    )
    assert rc == 0, err
    summary = json.loads(out)
    assert -180.0 < summary['psi_deg'] <= 180.0
    f = load_frame_npz(tmp_path / 'f.npz')
    assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))


def test_yaw_minus_180_and_180_give_the_same_psi(tmp_path, capsys):
    psis = []
    for yaw in ('-180', '180', '540'):
        rc, out, _ = run(
            [
                'render',
                '--stride',
                '64',
                '--sun-azimuth',
                '0',
                '--sun-altitude',
                '40',
                '--yaw',
                yaw,
                '--out',
                str(tmp_path / 'f.npz'),
            ],
            capsys,
        )
        psis.append(json.loads(out)['psi_deg'])
    assert psis == [180.0, 180.0, 180.0]


# --------------------------------------------------------------------------------------------
# sun
# --------------------------------------------------------------------------------------------
SUN_BAD_ARGS = [
    (['--lon', '181'], 'longitude'),
    (['--lon=-inf'], 'longitude'),
    (['--lat', '-90.0001'], 'latitude'),
    (['--altitude-m', '1e6'], 'altitude'),
    (['--altitude-m', 'nan'], 'altitude'),
    (['--pressure-hpa', '0'], 'pressure'),
    (['--pressure-hpa', 'nan'], 'pressure'),
    (['--temperature-c', 'nan'], 'temperature'),
    (['--temperature-c', '1000'], 'temperature'),
    (['--time', ''], 'ISO 8601'),
    (['--time', '2023-02-29'], 'ISO 8601'),
    (['--time', '2024-06-21T25:00'], 'ISO 8601'),
    (['--time', '2024-01-01T00:00:00+25:00'], 'ISO 8601'),
    (['--time', '10000-01-01'], 'ISO 8601'),
    (['--time=-3000-01-01'], 'ISO 8601'),
    (['--model', 'grena'], 'invalid choice'),
    (['--lat', '0x1p'], '--lat'),
]


@pytest.mark.parametrize('argv, words', SUN_BAD_ARGS)
def test_sun_bad_arguments(argv, words, capsys):
    base = {'--lat': '32', '--lon': '118.8', '--time': GOOD_TIME}
    for k in list(base):
        if any(a == k or a.startswith(k + '=') for a in argv):
            del base[k]
    full = ['sun'] + [x for kv in base.items() for x in kv] + argv
    assert_user_error(*run(full, capsys), words)


@pytest.mark.parametrize('missing', ['--lat', '--lon', '--time'])
def test_sun_missing_required_argument(missing, capsys):
    base = {'--lat': '32', '--lon': '118.8', '--time': GOOD_TIME}
    del base[missing]
    assert_user_error(*run(['sun'] + [x for kv in base.items() for x in kv], capsys), missing)


@pytest.mark.parametrize(
    'lat, lon, time',
    [
        ('90', '180', '2024-06-21T00:00:00Z'),
        ('-90', '-180', '2024-12-21T12:00Z'),
        ('0', '0', '2024-03-20T12:07:00Z'),
        ('23.44', '0', '2024-06-20T12:00Z'),
        ('45', '0', '2024-02-29T06:00:00+00:00'),
    ],
)
def test_sun_edge_values_give_finite_json(lat, lon, time, capsys):
    rc, out, err = run(['sun', '--lat', lat, '--lon', lon, '--time', time], capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert 0.0 <= d['azimuth_deg'] < 360.0 and -90.0 <= d['altitude_deg'] <= 90.0


# --------------------------------------------------------------------------------------------
# record-sim
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'argv, words',
    [
        (['--duration', '0'], 'duration'),
        (['--duration', '-1'], 'duration'),
        (['--duration', 'nan'], 'duration'),
        (['--duration', '1e9'], 'duration'),
        (['--rate', '0'], 'rate'),
        (['--rate', 'inf'], 'rate'),
        (['--pitch', '95'], 'pitch'),
        (['--roll', 'nan'], 'roll'),
        (['--imu-noise', '-1'], 'noise'),
        (['--reference-noise', 'nan'], 'noise'),
        (['--turns', 'nan'], 'turns'),
        (['--seed', '-1'], 'seed'),
        (['--reference-rate', '0'], 'reference rate'),
        (['--imu-rate', '-5'], 'rate'),
        (['--storage', 'rosbag1'], 'invalid choice'),
        (['--encoding', 'rgb8'], 'invalid choice'),
        (['--duration', 'ten'], '--duration'),
    ],
)
def test_record_sim_bad_arguments(argv, words, tmp_path, capsys):
    base = ['record-sim', '--duration', '1', '--out', str(tmp_path / 'bag')]
    assert_user_error(*run(base + argv, capsys), words)
    assert not (tmp_path / 'bag').exists()


@pytest.mark.parametrize(
    'kind, option, words',
    [
        ('missing', '--scene', 'does not exist'),
        ('missing', '--topics', 'does not exist'),
        ('not_mapping', '--scene', 'mapping'),
        ('directory', '--topics', ''),
        ('binary', '--scene', ''),
        ('binary', '--topics', ''),
    ],
)
def test_record_sim_bad_files(files, kind, option, words, tmp_path, capsys):
    argv = [
        'record-sim',
        '--duration',
        '1',
        '--out',
        str(tmp_path / 'bag'),
        option,
        str(files[kind]),
    ]
    assert_user_error(*run(argv, capsys), words)


def test_record_sim_refuses_to_overwrite(files, capsys):
    assert_user_error(
        *run(['record-sim', '--duration', '1', '--out', str(files['directory'])], capsys), 'exists'
    )


# --------------------------------------------------------------------------------------------
# replay
# --------------------------------------------------------------------------------------------
@pytest.fixture
def evil_bag(tmp_path):
    d = tmp_path / 'evilbag'
    d.mkdir()
    (d / 'metadata.yaml').write_text(
        "rosbag2_bagfile_information: !!python/object/apply:builtins.open ['%s', 'w']\n"
        % (tmp_path / 'PWNED')
    )
    return d


@pytest.mark.parametrize(
    'bag, extra, words',
    [
        ('missing', [], 'does not exist'),
        ('directory', [], 'metadata.yaml'),
        ('a_file', [], 'rosbag2'),
        ('evil', [], 'not a readable rosbag2'),
        ('directory', ['--stride', '0'], 'stride'),
        ('directory', ['--knob', 'foo'], 'knob'),
        ('directory', ['--methods', 'bogus'], 'bogus'),
        ('directory', ['--prior', 'gps'], 'invalid choice'),
        ('directory', ['--topics', '/nonexistent.yaml'], 'exist'),
        ('directory', ['--topics', 'BINARY'], ''),
        ('directory', ['--error-map', '/nonexistent/map.npz'], 'map'),
    ],
)
def test_replay_bad_input(files, evil_bag, bag, extra, words, tmp_path, capsys):
    path = evil_bag if bag == 'evil' else files[bag]
    extra = [str(files['binary']) if x == 'BINARY' else x for x in extra]
    assert_user_error(
        *run(['replay', str(path), '--out', str(tmp_path / 'out')] + extra, capsys), words
    )
    assert not (tmp_path / 'PWNED').exists()


# --------------------------------------------------------------------------------------------
# errormap (every case fails before a sweep starts)
# --------------------------------------------------------------------------------------------
ERRORMAP_OK = {'--sun-altitude': '20', '--yaw': '0', '--pitch': '0', '--roll': '0'}


@pytest.mark.parametrize(
    'over, words',
    [
        ({'--sun-altitude': '0:10:0'}, 'STEP'),
        ({'--sun-altitude': '10:0:5'}, '>= A'),
        ({'--sun-altitude': 'nan'}, 'finite'),
        ({'--sun-altitude': '0:1e9:1e-9'}, 'more than'),
        ({'--sun-altitude': '95'}, 'sun-altitude'),
        ({'--yaw': 'a:b:c'}, 'yaw'),
        ({'--pitch': '-90'}, 'pitch'),
        ({'--roll': 'inf'}, 'roll'),
        ({'--pitch': '80'}, 'tilt limit'),
        ({'--methods': 'bogus'}, 'bogus'),
        ({'--methods': ','}, 'empty'),
        ({'--stride': '0'}, 'stride'),
        ({'--workers': '0'}, 'workers'),
        ({'--tilt-limit': 'nan'}, 'tilt-limit'),
        ({'--support': '3'}, 'invalid choice'),
        ({'--out': 'e.txt'}, '.npz'),
        ({'--scene': '/nonexistent.yaml'}, 'does not exist'),
    ],
)
def test_errormap_bad_arguments(over, words, tmp_path, capsys):
    args = dict(ERRORMAP_OK, **{'--out': str(tmp_path / 'e.npz'), '--no-progress': None})
    args.update(over)
    argv = ['errormap'] + [x for k, v in args.items() for x in ((k,) if v is None else (k, v))]
    assert_user_error(*run(argv, capsys), words)
    assert not (tmp_path / 'e.npz').exists()


@pytest.mark.parametrize('case', ['binary_scene', 'out_under_a_file'])
def test_errormap_bad_files(files, case, tmp_path, capsys):
    args = dict(ERRORMAP_OK, **{'--out': str(tmp_path / 'e.npz'), '--no-progress': None})
    if case == 'binary_scene':
        args['--scene'] = str(files['binary'])
    else:
        args['--out'] = str(files['a_file'] / 'e.npz')
    argv = ['errormap'] + [x for k, v in args.items() for x in ((k,) if v is None else (k, v))]
    assert_user_error(*run(argv, capsys))


# --------------------------------------------------------------------------------------------
# allowable-tilt and plot (on a small synthetic map)
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def small_map(tmp_path_factory):
    from polarization_compass.errormap import ErrorMap

    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    shape = (1, alt.size, yaw.size, tilt.size, tilt.size)
    p = tmp_path_factory.mktemp('map') / 'm.npz'
    ErrorMap(
        np.full(shape, 0.5),
        np.zeros(shape, np.int8),
        ('least_squares',),
        alt,
        yaw,
        tilt,
        tilt,
        meta={'domain': {'tilt_limit_deg': 30.0}},
    ).save(p)
    return p


@pytest.mark.parametrize(
    'argv, words',
    [
        (['--max-error', 'nan'], 'max-error'),
        (['--max-error', '-1'], 'max-error'),
        (['--max-error', '0'], 'max-error'),
        (['--max-error', '1', '--sun-altitude', '95'], 'outside the map'),
        (['--max-error', '1', '--sun-altitude', 'nan'], 'altitude'),
        (['--max-error', '1', '--methods', 'bogus'], 'bogus'),
        (['--max-error', 'x'], '--max-error'),
    ],
)
def test_allowable_tilt_bad_arguments(small_map, argv, words, capsys):
    assert_user_error(*run(['allowable-tilt', '--map', str(small_map)] + argv, capsys), words)


@pytest.mark.parametrize(
    'kind, words',
    [('missing', 'does not exist'), ('directory', ''), ('binary', ''), ('python_tag', '')],
)
def test_allowable_tilt_bad_map_files(files, kind, words, capsys):
    assert_user_error(
        *run(['allowable-tilt', '--max-error', '1', '--map', str(files[kind])], capsys), words
    )


@pytest.mark.parametrize(
    'argv, words',
    [
        (['--figure', 'fig99'], 'invalid choice'),
        (['--figure', 'fig8', '--pitch', '13'], 'not a node'),
        (['--figure', 'fig8', '--pitch', 'nan'], 'pitch'),
        (['--figure', 'fig7', '--sun-altitude', 'inf'], 'altitude'),
        (['--figure', 'fig14', '--method', 'bogus'], 'bogus'),
        (['--figure', 'fig7', '--methods', 'bogus'], 'bogus'),
    ],
)
def test_plot_bad_arguments(small_map, argv, words, tmp_path, capsys):
    assert_user_error(
        *run(['plot', str(small_map), '--out', str(tmp_path / 'x.png')] + argv, capsys), words
    )
    assert not (tmp_path / 'x.png').exists()


@pytest.mark.parametrize('where, words', [('x.txt', '.png'), ('plain.txt/x.png', '')])
def test_plot_bad_output_paths(small_map, files, where, words, tmp_path, capsys):
    out = files['a_file'].parent / where if where.startswith('plain') else tmp_path / where
    assert_user_error(
        *run(['plot', str(small_map), '--figure', 'fig7', '--out', str(out)], capsys), words
    )


def test_plot_bad_map_file(files, tmp_path, capsys):
    assert_user_error(
        *run(
            ['plot', str(files['binary']), '--figure', 'fig7', '--out', str(tmp_path / 'x.png')],
            capsys,
        )
    )


# --------------------------------------------------------------------------------------------
# sim: bad input must be refused before the expensive part (an error-map sweep, 11 nodes)
# --------------------------------------------------------------------------------------------
class _Started(Exception):
    """Raised by the patched expensive steps: reaching them with bad input is the failure."""


@pytest.fixture
def no_expensive_sim(monkeypatch):
    from polarization_compass.cli import cmd_sim

    def started(*a, **k):
        raise _Started('the sim started its expensive part')

    monkeypatch.setattr(cmd_sim, 'ensure_error_map', started)
    monkeypatch.setattr(cmd_sim, '_run_graph', started)


@pytest.mark.parametrize(
    'argv, words',
    [
        (['--rate', '0'], 'rate'),
        (['--turns', 'nan'], 'turns'),
        (['--time-scale', '0'], 'time-scale'),
        (['--pitch', '95'], 'pitch'),
        (['--roll', 'nan'], 'roll'),
        (['--methods', 'bogus'], 'bogus'),
        (['--encoding', 'rgb8'], 'invalid choice'),
        (['--error-map', '/nonexistent/m.npz'], 'does not exist'),
        (['--timeout', '-1'], 'timeout'),
        (['--timeout', 'nan'], 'timeout'),
        (['--turn-rate', 'nan'], 'turn-rate'),
        (['--turn-rate', '0'], 'turn-rate'),
        (['--scene', '/nonexistent/scene.yaml'], 'scene'),
    ],
)
def test_sim_bad_arguments_are_refused_before_any_work(
    no_expensive_sim, argv, words, tmp_path, capsys
):
    assert_user_error(*run(['sim', '--out', str(tmp_path / 'sim')] + argv, capsys), words)


# --------------------------------------------------------------------------------------------
# every registered command
# --------------------------------------------------------------------------------------------
def registered_commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == '_SubParsersAction')
    return sorted(sub.choices)


def test_the_commands_this_file_checks_by_name_are_registered():
    assert {
        'sun',
        'render',
        'record-sim',
        'replay',
        'errormap',
        'allowable-tilt',
        'plot',
        'sim',
    } <= set(registered_commands())


@pytest.mark.parametrize('cmd', registered_commands())
def test_every_command_rejects_an_unknown_option_in_one_line(cmd, capsys):
    assert_user_error(*run([cmd, '--no-such-option-xyz'], capsys))  # (or "arguments are required")


@pytest.mark.parametrize('cmd', registered_commands())
def test_every_command_has_help_that_exits_0(cmd, capsys):
    rc, out, err = run([cmd, '--help'], capsys)
    assert rc == 0 and cmd in out and err == ''


def test_unknown_command_and_no_command(capsys):
    assert_user_error(*run(['frobnicate'], capsys), 'invalid choice')
    rc, out, err = run([], capsys)
    assert rc == 2 and 'Traceback' not in err


# --------------------------------------------------------------------------------------------
# what a user sees: the console entry point in a subprocess
# --------------------------------------------------------------------------------------------
def cli(args, **kw):
    env = dict(os.environ)
    env.pop('POLARIZATION_COMPASS_DEBUG', None)
    return subprocess.run(
        [sys.executable, '-m', 'polarization_compass.cli'] + args,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        **kw,
    )


def test_subprocess_bad_inputs_never_print_a_traceback(files, tmp_path):
    cases = [
        [
            'render',
            '--scene',
            str(files['binary']),
            '--out',
            str(tmp_path / 'f.npz'),
        ],  # the exit-70 bug
        ['render', '--scene', str(files['python_tag']), '--out', str(tmp_path / 'f.npz')],
        ['render', '--stride', '64', '--yaw', 'nan', '--out', str(tmp_path / 'f.npz')],
    ]
    for args in cases:
        p = cli(args)
        assert 'Traceback' not in p.stderr, (args, p.stderr)
        assert p.returncode in (2, 70) and p.stdout == '', (args, p.returncode)
    assert not (tmp_path / 'PWNED').exists()
    assert (
        p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    )  # the last case: a plain user error


def test_subprocess_closed_stdout_pipe_is_not_an_internal_error():
    with subprocess.Popen(
        [
            sys.executable,
            '-m',
            'polarization_compass.cli',
            'sun',
            '--lat',
            '1',
            '--lon',
            '2',
            '--time',
            GOOD_TIME,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    ) as p:
        p.stdout.close()  # the reader is gone before the command writes
        err = p.stderr.read().decode()
        rc = p.wait(timeout=120)
    assert 'Traceback' not in err
    assert 'internal error' not in err and rc != 70, (rc, err)


# --------------------------------------------------------------------------------------------
# issue 18: every command walked with hostile files (recursion, bombs, special files, bad types)
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def hostile(tmp_path_factory):
    """
    Hostile inputs by name.

    Bombs are small compressed files declaring huge arrays in their headers
    (never allocated here); /dev/zero and a FIFO stand for files that never end or block.
    """
    import io
    import zipfile

    d = tmp_path_factory.mktemp('hostile')
    f = {}
    f['deep_yaml'] = d / 'deep.yaml'
    f['deep_yaml'].write_text('name: ' + '[' * 20000 + ']' * 20000 + '\n')
    f['bad_date_yaml'] = d / 'date.yaml'
    f['bad_date_yaml'].write_text('time_utc: 2023-02-30\n')
    f['width_true_yaml'] = d / 'wtrue.yaml'
    f['width_true_yaml'].write_text('camera: {width_px: true}\n')
    f['dev_zero'] = d / 'zero.yaml'
    os.symlink('/dev/zero', f['dev_zero'])
    f['fifo'] = d / 'fifo.yaml'
    os.mkfifo(f['fifo'])

    def npy(shape, dtype='<f8', payload=1 << 16):
        b = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            b, {'descr': dtype, 'fortran_order': False, 'shape': shape}
        )
        return b.getvalue() + bytes(payload)

    def arr(a):
        b = io.BytesIO()
        np.save(b, a, allow_pickle=False)
        return b.getvalue()

    def npz(path, members):
        with zipfile.ZipFile(path, 'w', compression=zipfile.ZIP_DEFLATED) as zf:
            for k, v in members.items():
                zf.writestr(k + '.npy', v if isinstance(v, bytes) else arr(v))
        return path

    shape = (4, 6)
    frame = {
        'aop_rad': np.zeros(shape, np.float32),
        'dop': np.zeros(shape, np.float32),
        'valid': np.ones(shape, bool),
        'x_px': np.ones(shape),
        'y_px': np.ones(shape),
        'meta': np.array(json.dumps({'camera': {'width_px': 6, 'height_px': 4}})),
    }
    f['frame_bomb'] = npz(d / 'frame_bomb.npz', dict(frame, aop_rad=npy((10000, 20000))))
    f['frame_deep_meta'] = npz(
        d / 'frame_deep.npz', dict(frame, meta=np.array('{"a":' * 100000 + '1' + '}' * 100000))
    )
    mosaic_frame = dict(
        frame,
        mosaic=np.zeros((8, 12), np.uint16),
        x_px=np.tile(np.arange(1.5, 12, 2.0), (4, 1)),
        y_px=np.tile(np.arange(1.5, 8, 2.0)[:, None], (1, 6)),
    )
    for name, sensor in [
        ('frame_bad_bits', {'quantization_bits': 'twelve'}),
        ('frame_bad_sensor', ['mosaic']),
        ('frame_huge_bits', {'quantization_bits': 10**9}),
        ('frame_bad_exposure', {'exposure': 3}),
    ]:
        meta = {
            'camera': {'width_px': 12, 'height_px': 8},
            'sun_azimuth_deg': 180.0,
            'sun_altitude_deg': 30.0,
            'sensor': sensor,
        }
        f[name] = npz(d / f'{name}.npz', dict(mosaic_frame, meta=np.array(json.dumps(meta))))
    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    mshape = (1, alt.size, yaw.size, tilt.size, tilt.size)
    good_map = {
        'error_deg': np.zeros(mshape),
        'status': np.zeros(mshape, np.int8),
        'methods': np.array(['least_squares']),
        'sun_altitude_deg': alt,
        'yaw_deg': yaw,
        'pitch_deg': tilt,
        'roll_deg': tilt,
        'meta': np.array(json.dumps({'domain': {'tilt_limit_deg': 30.0}})),
    }
    f['map_deep_meta'] = npz(
        d / 'map_deep.npz', dict(good_map, meta=np.array('{"a":' * 100000 + '1' + '}' * 100000))
    )
    big = (1, 2000, 2000, 61, 61)  # 1.5e10 cells declared
    f['map_bomb'] = npz(
        d / 'map_bomb.npz',
        dict(
            good_map,
            error_deg=npy(big),
            status=npy(big, '|i1'),
            sun_altitude_deg=np.arange(2000.0),
            yaw_deg=np.arange(2000.0) / 10,
            pitch_deg=np.arange(61.0) - 30,
            roll_deg=np.arange(61.0) - 30,
        ),
    )
    f['map_fifo'] = d / 'map_fifo.npz'
    os.mkfifo(f['map_fifo'])
    f['npz_dev_zero'] = d / 'zero.npz'
    os.symlink('/dev/zero', f['npz_dev_zero'])
    f['npy_bomb'] = d / 'bomb.npy'  # a raw-mosaic .npy declaring 1.6 GB
    f['npy_bomb'].write_bytes(npy((10000, 20000), '<u2', payload=1 << 10))
    return f


def _hostile_cases():
    """
    Return the hostile command lines and the words expected in the one line.

    (command line with {name} placeholders for hostile files, words expected in the one line).
    """
    cases = []
    for scene in ('deep_yaml', 'bad_date_yaml', 'width_true_yaml', 'dev_zero', 'fifo'):
        words = {
            'deep_yaml': 'nested',
            'bad_date_yaml': 'day is out of range',
            'width_true_yaml': 'width_px',
            'dev_zero': 'device',
            'fifo': 'FIFO',
        }[scene]
        cases += [
            (['render', '--scene', '{%s}' % scene, '--out', '{out}/f.npz'], words),
            (
                [
                    'errormap',
                    '--scene',
                    '{%s}' % scene,
                    '--sun-altitude',
                    '20',
                    '--yaw',
                    '0',
                    '--pitch',
                    '0',
                    '--roll',
                    '0',
                    '--no-progress',
                    '--out',
                    '{out}/e.npz',
                ],
                words,
            ),
            (
                ['record-sim', '--duration', '1', '--scene', '{%s}' % scene, '--out', '{out}/bag'],
                words,
            ),
            (['sim', '--scene', '{%s}' % scene, '--out', '{out}/sim'], words),
            (['budget', '--scene', '{%s}' % scene, '--samples', '1', '--out', '{out}/b'], words),
        ]
        if scene != 'width_true_yaml':
            tw = (
                '' if scene == 'bad_date_yaml' else words
            )  # (a topic map has no time: any one line)
            cases += [
                (
                    [
                        'record-sim',
                        '--duration',
                        '1',
                        '--topics',
                        '{%s}' % scene,
                        '--out',
                        '{out}/bag',
                    ],
                    tw,
                ),
                (['replay', '{out}', '--topics', '{%s}' % scene, '--out', '{out}/r'], tw),
            ]
    for frame, words in [
        ('frame_bomb', 'declares shape'),
        ('frame_deep_meta', 'nested'),
        ('frame_bad_bits', 'quantization_bits'),
        ('frame_bad_sensor', 'sensor'),
        ('frame_huge_bits', 'quantization_bits'),
        ('frame_bad_exposure', 'exposure'),
        ('npz_dev_zero', 'device'),
        ('map_fifo', 'FIFO'),
    ]:
        cases.append((['estimate', '{%s}' % frame], words))
    cases += [
        (['estimate', '{npy_bomb}', '--camera', '{deep_yaml}'], ''),
        (['estimate', '{npy_bomb}'], ''),
    ]
    for inp, cam in (
        ('npy_bomb', '{deep_yaml}'),
        ('frame_bomb', '{dev_zero}'),
        ('map_fifo', '{fifo}'),
        ('npz_dev_zero', '{width_true_yaml}'),
    ):
        cases.append((['check-polarizer', '{%s}' % inp, '--camera', cam], ''))
    for m, words in [
        ('map_deep_meta', 'nested'),
        ('map_bomb', 'declare'),
        ('dev_zero', 'device'),
        ('map_fifo', 'FIFO'),
    ]:
        cases += [
            (['allowable-tilt', '--max-error', '1', '--map', '{%s}' % m], words),
            (['plot', '{%s}' % m, '--figure', 'fig7', '--out', '{out}/x.png'], words),
            (['sim', '--error-map', '{%s}' % m, '--out', '{out}/sim'], words),
        ]
    site = ['--lat', '32', '--lon', '118', '--time', GOOD_TIME]
    for bad in (
        'deep_yaml',
        'dev_zero',
        'fifo',
        'map_bomb',
    ):  # photodiode-array commands: any one line
        geometry = '{%s}' % bad if bad != 'map_bomb' else '{deep_yaml}'
        recording = '{%s}' % bad if bad != 'deep_yaml' else '{map_bomb}'
        cases += [
            (['calibrate-array', recording, '--geometry', geometry, '--out', '{out}/g.yaml'], ''),
            (
                ['calibrate-mount', recording, '--geometry', geometry, '--out', '{out}/m.yaml']
                + site,
                '',
            ),
            (['check-array', recording, '--geometry', geometry] + site, ''),
            (
                ['estimate-array', recording, '--geometry', geometry, '--out', '{out}/h.csv']
                + site,
                '',
            ),
        ]
    cases += [
        (['render', '--stride', '64', '--seed', '-5', '--out', '{out}/f.npz'], '--seed'),
        (['render', '--stride', '64', '--seed', str(2**64), '--out', '{out}/f.npz'], '--seed'),
    ]
    return cases


def test_the_hostile_walk_covers_every_command_that_reads_a_file():
    walked = {argv[0] for argv, _ in _hostile_cases()}
    readers = set(registered_commands()) - {'sun'}  # sun reads no file
    assert readers <= walked, readers - walked


@pytest.mark.parametrize(
    'argv, words', _hostile_cases(), ids=lambda x: ' '.join(x) if isinstance(x, list) else x
)
def test_every_command_fed_hostile_files_exits_2_with_one_line(
    hostile, no_expensive_sim, argv, words, tmp_path, capsys
):
    """
    Every command fed hostile files exits 2 with one line.

    Issue 18: RecursionError, memory bombs, special files, bad dates/types/seeds ended in exit 70,
    20 GB of RSS or a hang. Now one line and exit 2 each, before any expensive work (sim's is
    patched to raise).
    """
    full = [a.format(out=tmp_path, **{k: str(v) for k, v in hostile.items()}) for a in argv]
    assert_user_error(*run(full, capsys), words)
