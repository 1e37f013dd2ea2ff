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
Every name each launch file uses exists and is consistent.

Every executable, parameter file, parameter and remapping each launch file names (via graphs/)
exists and is consistent, checked without running anything. Independent sources: setup.py's
console_scripts (parsed as text), the YAML files on disk, the node parameter specifications, and
the launch files' own source.
"""

import ast
import fnmatch
import importlib
from pathlib import Path
import re

from polarization_compass import graphs
from polarization_compass.specs import topics
from polarization_compass.specs.params import (
    ALL_METHODS,
    knob_params,
    KNOB_PREFIX,
    PAPER_METHODS,
    spec_by_name,
    SPECS,
    validate_value,
)
import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent

ARG_SETS = {
    'sim': [
        {},
        {
            'methods': 'least_squares',
            'tilt_aware': 'false',
            'lockstep': 'true',
            'encoding': '32FC1',
        },
        {'methods': 'zenith,symmetry', 'rate_hz': '5', 'pitch_deg': '-10', 'roll_deg': '15'},
        {'methods': 'least_squares', 'attitude_source': 'tf', 'turns': '0.5'},
    ],
    'compass': [
        {},
        {'method': 'tilt_aware'},
        {
            'method': 'zenith',
            'correction': 'none',
            'namespace': 'front',
            'image_topic': '/pol/image_raw',
            'imu_topic': '/vectornav/imu',
            'site_source': 'parameters',
            'use_sim_time': 'true',
        },
    ],
    'replay': [{}, {'methods': 'sm_asm', 'tilt_aware': 'false', 'site_source': 'parameters'}],
    'fusion': [{}, {'fuse': 'least_squares,tilt_aware,none', 'turns': '0.25'}],
}


def console_scripts() -> dict:
    """
    Return name -> 'module:function' from setup.py's entry points, read as text.

    It is read as text, not by importing setup.py.
    """
    text = (ROOT / 'setup.py').read_text()
    return dict(re.findall(r'["\']([\w-]+)\s*=\s*([\w.]+:\w+)["\']', text))


def data_file_globs() -> list[tuple[str, str]]:
    """(install dir, source glob) pairs of setup.py's data_files."""
    text = (ROOT / 'setup.py').read_text()
    # either quote style: the formatter writes single quotes
    text = text.replace('"', "'")
    return re.findall(r"\('share/' \+ PACKAGE \+ '([^']*)', (?:glob\('([^']+)'\))", text) + [
        (d, g)
        for d, g in re.findall(
            r"\('share/' \+ PACKAGE \+ '([^']*)', glob\('[^']+'\) \+ glob\('([^']+)'\)\)", text
        )
    ]


def all_graphs():
    for name, sets in ARG_SETS.items():
        for args in sets:
            yield name, args, graphs.build(name, args)


def declared_params(node: graphs.NodeSpec) -> dict:
    specs = spec_by_name(SPECS[node.executable])
    if node.executable == 'heading_estimator':
        specs.update(spec_by_name(knob_params(node.parameters['method'])))
    return specs


@pytest.mark.parametrize(
    'name,args,graph', list(all_graphs()), ids=lambda x: str(x) if isinstance(x, str) else ''
)
def test_graph_wiring_is_consistent(name, args, graph):
    assert graph.check() == []
    scripts = console_scripts()
    for n in graph.nodes:
        if n.package != graphs.PACKAGE:  # robot_localization's ekf_node: test_fusion_graph_*
            continue
        assert n.executable in scripts, f'{n.executable} is not a console script in setup.py'
        assert scripts[n.executable] == f'polarization_compass.nodes.{n.executable}:main'
        for f in n.param_files:
            assert (ROOT / f).is_file(), f
            assert any(fnmatch.fnmatch(f, g) for _, g in data_file_globs()), (
                f'{f} is not installed by setup.py'
            )
        used = {t for t, _ in n.publishes} | {t for t, _ in n.subscribes}
        for a, b in n.remappings:
            assert a in used, f'{n.name} remaps {a}, a topic it does not use'
            assert re.fullmatch(r'/?[A-Za-z][\w/]*', b), b


def test_every_console_script_module_has_main():
    for name, target in console_scripts().items():
        mod, func = target.split(':')
        assert callable(getattr(importlib.import_module(mod), func)), target


@pytest.mark.parametrize(
    'name,args,graph', list(all_graphs()), ids=lambda x: str(x) if isinstance(x, str) else ''
)
def test_every_parameter_is_declared_typed_and_in_range(name, args, graph):
    for n in graph.nodes:
        if n.package != graphs.PACKAGE:  # robot_localization's ekf_node: test_fusion_graph_*
            continue
        specs = declared_params(n)
        values = {}
        for f in n.param_files:
            doc = yaml.safe_load((ROOT / f).read_text())
            assert list(doc) == ['/**'], (
                f'{f}: use the /** wildcard so that every instance reads it'
            )
            values.update(_flatten(doc['/**']['ros__parameters']))
        values.update(n.parameters)
        for key, v in values.items():
            if key == 'use_sim_time':
                assert isinstance(v, bool)
                continue
            assert key in specs, f'{n.name}: parameter {key} is not declared by {n.executable}'
            p = specs[key]
            kind = {bool: 'bool', int: 'int', float: 'float', str: 'str'}.get(type(v), 'list')
            if p.kind in ('str_list', 'float_list'):
                assert kind == 'list', f'{key} must be a list'
            else:
                # ROS parameters are statically typed: 10 is not a double
                assert kind == p.kind, f'{n.name}: {key} = {v!r} is {kind}, declared {p.kind}'
            assert validate_value(p, v) is None, validate_value(p, v)


def _flatten(d, prefix=''):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f'{prefix}{k}.'))
        else:
            out[prefix + k] = v
    return out


def test_knob_parameters_are_the_estimators_knobs():
    from polarization_compass.estimators import estimator_names, make_estimator

    for m in estimator_names():
        names = {p.name for p in knob_params(m)}
        # independent source: the estimator class's own knob table
        assert names == {KNOB_PREFIX + k for k in type(make_estimator(m)).knob_specs()}
    g = graphs.build('sim')
    assert g.node('heading_estimator_least_squares').parameters['knob.stride'] == 8
    assert (
        'knob.stride' not in g.node('heading_estimator_zenith').parameters
    )  # zenith reads its window


@pytest.mark.parametrize(
    'name,args,graph', list(all_graphs()), ids=lambda x: str(x) if isinstance(x, str) else ''
)
def test_command_line_parameters_round_trip(name, args, graph):
    share = graphs.share_dir()
    for n in graph.nodes:
        argv = n.ros_arguments(share)
        assert argv[:3] == ['--ros-args', '-r', f'__node:={n.name}']
        got = {}
        for flag, val in zip(argv, argv[1:]):
            if flag == '-p':
                k, v = val.split(':=', 1)
                got[k] = yaml.safe_load(v)
            if flag == '--params-file':
                assert Path(val).is_file()
        assert got == n.parameters


def test_default_graphs_connect_without_remapping():
    g = graphs.build('sim')
    assert all(n.remappings == () for n in g.nodes)
    pubs = g.published_topics()
    # the chain simulator -> estimator -> corrector -> evaluator, by name
    for m in PAPER_METHODS:
        t = topics.method_topics(m)
        assert '/' + t['heading_raw'] in pubs and '/' + t['heading'] in pubs
        assert ('/' + t['heading'], topics.T_IMU) in g.node(
            'error_evaluator'
        ).resolved_subscribes()
        assert ('/' + t['heading_raw'], topics.T_IMU) in g.node(
            f'tilt_corrector_{m}'
        ).resolved_subscribes()
    assert ('/' + topics.IMAGE, topics.T_IMAGE) in g.node(
        'heading_estimator_tilt_aware'
    ).resolved_subscribes()
    assert g.shutdown_with == 'sky_simulator'
    assert len(g.nodes) == 1 + 5 + 4 + 1


def test_fusion_graph_runs_ekf_node_from_the_shipped_config_on_the_graphs_topics():
    cfg = yaml.safe_load((ROOT / graphs.EKF_CONFIG).read_text())['ekf_filter_node']
    base = cfg['ros__parameters']
    assert base['imu0_relative'] is False and base['imu0_config'][5] is True
    assert any(fnmatch.fnmatch(graphs.EKF_CONFIG, g) for _, g in data_file_globs())
    g = graphs.build('fusion', {'fuse': 'least_squares,tilt_aware,none'})
    ekfs = [n for n in g.nodes if n.executable == 'ekf_node']
    assert [n.package for n in ekfs] == ['robot_localization'] * 3
    first, aware, none = ekfs
    # the file's own node with the file, unchanged but for sim time and the simulator's odometry
    assert (first.name, first.param_files) == ('ekf_filter_node', (graphs.EKF_CONFIG,))
    assert first.parameters == {
        'use_sim_time': True,
        'odom0': '/odometry/wheel',
        'imu0': '/compass/least_squares/heading',
    }
    assert base['imu0'] == first.parameters['imu0'] and base['odom0'] == '/odometry/wheel'
    assert first.resolved(topics.FILTERED) == '/odometry/filtered'
    # the others: the file's parameters inline, their own output, no TF
    for n, imu0 in ((aware, '/compass/tilt_aware/heading_raw'), (none, None)):
        assert n.param_files == () and n.parameters['publish_tf'] is False
        assert n.parameters.get('imu0') == imu0
        assert n.parameters['process_noise_covariance'] == base['process_noise_covariance']
        assert n.resolved(topics.FILTERED) != '/odometry/filtered'
    # every input is published by the graph; the simulator waits for the filters' subscriptions
    pubs = g.published_topics()
    for n in ekfs:
        for t, ty in n.resolved_subscribes():
            assert ty in pubs[t], (n.name, t)
    wait = ';'.join(g.node('sky_simulator').parameters['wait_for_downstream'])
    assert 'odometry/wheel=ekf_filter_node,ekf_filter_node_none,ekf_filter_node_tilt_aware' in wait
    ev = g.node('error_evaluator').parameters['fused_streams']
    assert ev == [
        'least_squares=/odometry/filtered',
        'tilt_aware=/odometry/filtered_tilt_aware',
        'odometry=/odometry/filtered_none',
    ]
    with pytest.raises(graphs.GraphError, match='does not run'):
        graphs.build('fusion', {'fuse': 'zenith'})


def test_real_camera_graph_checks_against_the_whole_sky_by_default():
    """
    The real camera graph checks against the whole sky by default.

    A real sky is not the model: the compass graph's estimator runs the whole-sky check unless told
    not to; the simulated graph's skies are the model, so the node's own default (off) stands
    there.
    """
    from polarization_compass.specs.params import SPECS as P

    node_default = {p.name: p.default for p in P['heading_estimator']}['sky_check']
    assert node_default is False
    for method in ('zenith', 'least_squares', 'tilt_aware'):
        est = graphs.build('compass', {'method': method}).node(f'heading_estimator_{method}')
        assert est.parameters['sky_check'] is True
    est = graphs.build('compass', {'method': 'zenith', 'sky_check': 'false'}).node(
        'heading_estimator_zenith'
    )
    assert est.parameters['sky_check'] is False
    for n in graphs.build('sim', {}).nodes:
        assert 'sky_check' not in n.parameters


def test_compass_graph_remaps_inputs_and_namespaces():
    g = graphs.build(
        'compass',
        {
            'method': 'zenith',
            'image_topic': '/pol/image_raw',
            'namespace': 'front',
            'imu_topic': '/vn/imu',
        },
    )
    est = g.node('heading_estimator_zenith')
    assert est.resolved(topics.IMAGE) == '/pol/image_raw'
    assert est.resolved(topics.CAMERA_INFO) == '/front/camera/camera_info'
    assert (
        est.resolved(topics.method_topics('zenith')['heading_raw'])
        == '/front/compass/zenith/heading_raw'
    )
    assert '/pol/image_raw' in g.external_inputs and '/vn/imu' in g.external_inputs
    assert g.check() == []
    assert [n.name for n in graphs.build('compass', {'method': 'tilt_aware'}).nodes] == [
        'heading_estimator_tilt_aware'
    ]


@pytest.mark.parametrize(
    'name, args, fix',
    [
        ('compass', {}, '/gps/fix'),
        ('compass', {'fix_topic': '/ublox/fix', 'namespace': 'front'}, '/ublox/fix'),
        ('compass', {'site_source': 'parameters'}, None),
        ('replay', {}, '/gps/fix'),
        ('replay', {'site_source': 'parameters'}, None),
        ('sim', {}, None),
    ],
)
def test_correctors_take_the_site_where_their_estimator_does(name, args, fix):
    """
    The corrector takes the site where its estimator does.

    The corrector looks the sun up in the error map: same site_source and fix topic as its
    estimator.
    """
    g = graphs.build(name, args)
    cors = [n for n in g.nodes if n.executable == 'tilt_corrector']
    assert cors
    for cor in cors:
        est = g.node(cor.name.replace('tilt_corrector', 'heading_estimator'))
        for n in (cor, est):
            subs = dict(n.resolved_subscribes())
            if fix is None:
                assert not any(t.endswith('fix') for t in subs), n.name
                assert n.parameters.get('site_source', 'parameters') == 'parameters'
            else:
                assert subs.get(fix) == topics.T_FIX, (n.name, subs)
                assert n.parameters['site_source'] == 'navsatfix'


def test_a_corrector_with_another_site_than_its_estimator_is_reported():
    import dataclasses

    g = graphs.build('compass', {'method': 'zenith'})
    cor = g.node('tilt_corrector_zenith')
    pubs, subs = topics.corrector_topics('zenith', 'parameters')
    wrong = dataclasses.replace(
        cor, subscribes=tuple(subs), parameters={**cor.parameters, 'site_source': 'parameters'}
    )
    bad = graphs.Graph(
        'x',
        '',
        tuple(wrong if n is cor else n for n in g.nodes),
        external_inputs=g.external_inputs,
    )
    problems = bad.check()
    assert any(
        'tilt_corrector_zenith takes the site from its parameters' in p for p in problems
    ), problems
    assert any('site_source' in p for p in problems), problems
    moved = dataclasses.replace(cor, parameters={**cor.parameters, 'latitude_deg': 0.0})
    bad = graphs.Graph(
        'x',
        '',
        tuple(moved if n is cor else n for n in g.nodes),
        external_inputs=g.external_inputs,
    )
    assert any('latitude_deg' in p for p in bad.check())


def test_estimator_and_corrector_files_give_the_same_site():
    est = yaml.safe_load((ROOT / 'config/heading_estimator.yaml').read_text())['/**'][
        'ros__parameters'
    ]
    cor = yaml.safe_load((ROOT / 'config/tilt_corrector.yaml').read_text())['/**'][
        'ros__parameters'
    ]
    for key in ('site_source', 'latitude_deg', 'longitude_deg', 'altitude_m', 'sun_model'):
        assert est[key] == cor[key], key


def test_a_broken_graph_is_reported():
    g = graphs.build('sim', {'methods': 'least_squares'})
    bad = graphs.Graph(
        'x', '', tuple(n for n in g.nodes if not n.name.startswith('heading_estimator'))
    )
    problems = bad.check()
    assert any('compass/least_squares/heading_raw' in p for p in problems)


def test_sim_graph_with_tf_attitude_renders_from_tf_it_broadcasts_without_odometry():
    """attitude_source:=tf: one source of attitude (TF), fed by the simulator's motion."""
    sim = graphs.build('sim').node('sky_simulator')
    assert 'attitude_source' not in sim.parameters  # motion, the file's default
    assert (topics.ODOM, topics.T_ODOMETRY) in sim.publishes
    g = graphs.build('sim', {'attitude_source': 'tf', 'turns': '0.5', 'turn_rate_deg_s': '-20'})
    assert g.check() == []
    p = g.node('sky_simulator').parameters
    assert p['attitude_source'] == 'tf' and p['motion_tf'] is True
    assert p['duration_s'] == pytest.approx(9.0)  # the run's length: TF does not count turns
    # no wheel odometry: its odom would be a second parent of base_link beside the TF's map
    assert topics.ODOM not in {t for t, _ in g.node('sky_simulator').publishes}
    assert [n.name for n in g.nodes] == [n.name for n in graphs.build('sim').nodes]
    assert g.shutdown_with == 'sky_simulator'
    until_stopped = graphs.build('sim', {'attitude_source': 'tf', 'turns': '0'})
    assert until_stopped.node('sky_simulator').parameters['duration_s'] == 0.0
    with pytest.raises(graphs.GraphError, match='attitude_source must be one of motion, tf'):
        graphs.build('sim', {'attitude_source': 'topic'})
    with pytest.raises(graphs.GraphError, match='attitude_source'):
        graphs.sim_graph(attitude_source='topic')


def test_bad_launch_arguments_are_refused():
    with pytest.raises(graphs.GraphError, match='rate_hz'):
        graphs.build('sim', {'rate_hz': 'fast'})
    with pytest.raises(graphs.GraphError, match='no launch argument'):
        graphs.build('sim', {'method': 'zenith'})
    with pytest.raises(graphs.GraphError, match='unknown item'):
        graphs.build('sim', {'methods': 'zenith,compass'})
    with pytest.raises(graphs.GraphError, match='one of'):
        graphs.build('compass', {'method': 'magnetometer'})
    with pytest.raises(graphs.GraphError, match='unknown graph'):
        graphs.build('teleop')


def test_launch_files_build_from_graphs_and_import_launch_lazily():
    files = sorted((ROOT / 'launch').glob('*.launch.py'))
    assert [f.name for f in files] == sorted(f'{g}.launch.py' for g in graphs.GRAPH_NAMES)
    for f in files:
        tree = ast.parse(f.read_text())
        top_imports = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
        assert top_imports == [], f'{f.name} imports at module level'
        fns = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert 'generate_launch_description' in fns
        calls = [
            c
            for c in ast.walk(fns['generate_launch_description'])
            if isinstance(c, ast.Call) and getattr(c.func, 'id', '') == 'launch_description'
        ]
        assert len(calls) == 1 and calls[0].args[0].value == f.name.split('.')[0]


def test_launch_description_without_launch_names_the_package():
    # here launch is absent (the repo's launch/ directory is only a namespace package): the
    # missing-dependency message is the behaviour; on a ROS install a LaunchDescription comes back
    try:
        from launch import LaunchDescription  # noqa: F401
    except ImportError:
        from polarization_compass.errors import MissingDependencyError

        with pytest.raises(MissingDependencyError, match='launch-ros'):
            graphs.launch_description('sim')
    else:
        ld = graphs.launch_description('sim')
        assert ld is not None


def test_fastdds_profile_is_shipped_and_installed():
    prof = ROOT / graphs.FASTDDS_PROFILE
    text = prof.read_text()
    assert '<type>SHM</type>' in text and 'useBuiltinTransports>false<' in text
    assert any(fnmatch.fnmatch(graphs.FASTDDS_PROFILE, g) for _, g in data_file_globs())


def test_every_method_in_params_is_a_method_name():
    assert set(PAPER_METHODS) < set(ALL_METHODS)
    assert graphs.share_dir() == ROOT


@pytest.mark.parametrize('doc', ['docs/ros.md', 'README.md'])
def test_docs_list_every_parameter(doc):
    from polarization_compass.specs.params import markdown_tables

    text = (ROOT / doc).read_text()
    assert markdown_tables() in text, (
        f'{doc} parameter tables are stale: paste params.markdown_tables()'
    )
    for node, specs in SPECS.items():
        for p in specs:
            assert f'| `{p.name}` |' in text, f'{doc} does not list {node}.{p.name}'


def test_readme_lists_every_topic_of_every_graph():
    import re

    text = (ROOT / 'README.md').read_text()
    seen = 0
    for name in ('sim', 'compass', 'replay'):
        for node in graphs.build(name).nodes:
            for topic, _ in tuple(node.publishes) + tuple(node.subscribes):
                generic = re.sub(r'compass/[a-z_]+/', 'compass/<m>/', topic.lstrip('/'))
                assert f'`{generic}`' in text or f'`/{generic}`' in text, (name, node.name, topic)
                seen += 1
    assert seen > 30


def test_node_command_falls_back_to_the_module_form(monkeypatch, tmp_path):
    """
    A node command falls back to the module form.

    On a ROS install the console scripts are in install/lib/<pkg>, on no PATH: run the module.
    """
    import sys

    from polarization_compass import graphs as G

    monkeypatch.setattr(sys, 'executable', str(tmp_path / 'python3'))
    monkeypatch.setenv('PATH', str(tmp_path))
    assert G.node_command('heading_estimator') == [
        str(tmp_path / 'python3'),
        '-m',
        'polarization_compass.nodes.heading_estimator',
    ]
    script = tmp_path / 'heading_estimator'
    script.write_text('#!/bin/sh\n')
    script.chmod(0o755)
    assert G.node_command('heading_estimator') == [str(script)]
