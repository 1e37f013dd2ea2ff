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
The estimator registry: one class plus one registration reaches every consumer.

The estimator registry: a method is one class with its facts plus one registration, and every
consumer (CLI, node parameters, graphs, error-map sweeps, figures, the replay) sees it without
further edits.

The toy methods return a heading fixed by their knob (psi = ``stride`` deg), so what each consumer
did with them is known independently of this code: the sweep's error is ``stride - yaw`` at the
declared sampling, the CLI prints psi = the stride it was given, and so on. Every check below would
fail if that consumer still read a hard-coded list of names, labels, costs or sweep knobs.
"""

import json

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.estimators import Knob, make_estimator, registry
from polarization_compass.estimators.base import Estimator, EstimatorError, HeadingResult, Status
import pytest

TOY, TOY_TILT = 'toy_const', 'toy_tilt'
BUILTIN = ('zenith', 'sm_asm', 'symmetry', 'least_squares', 'tilt_aware')


class ToyEstimator(Estimator):
    """Psi = stride (deg), whatever the sky: a heading every consumer can predict."""

    name = TOY
    label = 'Toy constant'
    style = ('tab:brown', '--')
    axial = False
    sweep_knobs = {'stride': 7}
    relative_cost = 100.0  # far above all built-ins together (~25)

    @classmethod
    def knob_specs(cls) -> dict:
        return {'stride': Knob(1, 'int', 1, 1024, doc='toy: psi in deg, and the pixel stride')}

    def __init__(self, **knobs):
        unknown = set(knobs) - set(self.knob_specs())
        if unknown:
            raise EstimatorError(f'{self.name}: unknown knob(s) {sorted(unknown)}')
        super().__init__(
            stride=self.knob_specs()['stride'].check('stride', knobs.get('stride', 1))
        )

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        return PixelSelection.strided(self.knobs['stride'])

    def estimate(self, obs, sigma: bool = True) -> HeadingResult:
        n = int(np.count_nonzero(obs.valid))
        if self.needs_tilt and (obs.pitch_deg is None or obs.roll_deg is None):
            return HeadingResult.failed(self.name, Status.BAD_INPUT, 'needs pitch and roll', n)
        return HeadingResult.from_psi(
            self.name,
            float(self.knobs['stride']),
            obs.sun_azimuth_deg,
            0.5 if sigma else None,
            n,
            1.0,
            False,
        )


class ToyTiltEstimator(ToyEstimator):
    """The same, declared to read the known tilt (so: no corrector, a direct method)."""

    name = TOY_TILT
    label = 'Toy tilt'
    style = ('tab:olive', ':')
    needs_tilt = True
    relative_cost = 0.01


@pytest.fixture
def toys():
    """
    Register both toy methods and remove them afterwards.

    Register both toys (one line each) and remove them afterwards, leaving the registry as it was.
    """
    before = registry.names()
    registry.register(ToyEstimator)
    registry.register(ToyTiltEstimator)
    try:
        yield
    finally:
        registry.unregister(TOY)
        registry.unregister(TOY_TILT)
        assert registry.names() == before


# ------------------------------------------------------------------------------------------------
# The registry itself
# ------------------------------------------------------------------------------------------------
def test_builtin_facts_and_order():
    assert registry.names() == BUILTIN
    assert registry.paper_methods() == BUILTIN[:4]
    assert registry.tilt_methods() == ('tilt_aware',)
    for n in BUILTIN:
        cls = registry.get(n)
        assert cls.name == n and issubclass(cls, Estimator)
        assert make_estimator(n).name == n
        assert isinstance(registry.label(n), str) and registry.label(n) != n
        assert registry.relative_cost(n) > 0
    assert registry.knob_names('zenith') >= {'window_px'} and 'stride' not in registry.knob_names(
        'zenith'
    )
    assert Estimator.knob_specs() == {}  # the base class: no knobs, nothing to probe


def test_registry_refuses_bad_registrations():
    class NoName(Estimator):
        pass

    class Clash(ToyEstimator):
        name = 'zenith'

    with pytest.raises(EstimatorError):
        registry.register(NoName)
    with pytest.raises(EstimatorError):
        registry.register(Clash)
    with pytest.raises(EstimatorError):
        registry.register(dict)
    with pytest.raises(EstimatorError, match='known: zenith'):
        registry.get('nope')
    assert registry.get('zenith').__name__ == 'ZenithEstimator'


def test_estimators_base_does_not_import_the_methods():
    """The registry imports the method modules; base (which they import) must not: no cycle."""
    import ast
    import inspect

    from polarization_compass.estimators import base

    tree = ast.parse(inspect.getsource(base))
    imported = {
        a.name if isinstance(n, ast.Import) else (n.module or '')
        for n in ast.walk(tree)
        if isinstance(n, (ast.Import, ast.ImportFrom))
        for a in n.names
    }
    for mod in ('methods', 'registry', 'zenith', 'sm_asm', 'symmetry', 'least_squares'):
        assert not any(i == mod or i.endswith('.' + mod) for i in imported), mod


# ------------------------------------------------------------------------------------------------
# A registered toy is seen everywhere
# ------------------------------------------------------------------------------------------------
def test_toy_in_the_cli(toys, tmp_path, capsys):
    from polarization_compass.cli import main
    from polarization_compass.frame_io import save_frame_npz
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene

    with pytest.raises(SystemExit) as e:
        main(['estimate', '--help'])
    assert e.value.code == 0
    help_text = ' '.join(capsys.readouterr().out.split())
    assert f'least_squares | tilt_aware | {TOY} | {TOY_TILT} | all (default)' in help_text
    assert f'(tilt_aware, {TOY_TILT} needs it' in help_text

    f = Renderer(Scene(pixels=PixelSelection.strided(4))).render(
        attitude=cv.CameraAttitude(170.0, -8.0, 5.0), sun=SunDirection(100.0, 35.0)
    )
    p = tmp_path / 'frame.npz'
    save_frame_npz(p, f)
    assert main(['estimate', str(p), '--method', TOY, '--stride', '5']) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r['method'] for r in rows] == [TOY]
    assert rows[0]['status'] == 'ok' and rows[0]['psi_deg'] == 5.0
    assert abs(cv.wrap_180_deg(rows[0]['bearing_deg'] - 105.0)) < 1e-9  # psi + sun azimuth 100
    assert main(['estimate', str(p), '--method', 'all', '--pitch', '-8', '--roll', '5']) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r['method'] for r in rows] == list(BUILTIN) + [TOY, TOY_TILT]
    assert rows[-1]['status'] == 'ok' and rows[-1]['psi_deg'] == 1.0  # default knob


def test_toy_in_the_node_params_and_pipeline(toys):
    from polarization_compass.evaluation_report import format_table
    from polarization_compass.pipeline import TiltAndPrior
    from polarization_compass.specs import params as P

    for specs in (P.ESTIMATOR, P.CORRECTOR):
        method = P.spec_by_name(specs)['method']
        assert P.validate_value(method, TOY) is None
        assert P.validate_value(method, 'nope') is not None
    ev = P.spec_by_name(P.EVALUATOR)
    assert P.validate_value(ev['methods'], ['zenith', TOY, TOY_TILT]) is None
    knob = {p.name: p for p in P.knob_params(TOY)}
    assert set(knob) == {P.KNOB_PREFIX + 'stride'}
    assert (knob['knob.stride'].default, knob['knob.stride'].lo, knob['knob.stride'].hi) == (
        1,
        1,
        1024,
    )
    assert P.knob_values(TOY, {'knob.stride': 9}) == {'stride': 9}
    assert TiltAndPrior(TOY_TILT).needs_tilt and not TiltAndPrior(TOY).needs_tilt
    table = format_table(
        {
            'streams': {
                f'{m}/raw': {
                    'count': 1,
                    'missed': 0,
                    'mean': 0.0,
                    'rms': 0.0,
                    'p95': 0.0,
                    'max': 0.0,
                }
                for m in (TOY_TILT, TOY, 'zenith')
            }
        }
    )
    rows = [ln.split()[:2] for ln in table.splitlines()[3:6]]
    assert rows == [['zenith', 'raw'], [TOY, 'raw'], [TOY_TILT, 'tilt-aware']]


def test_toy_in_the_graphs(toys):
    from polarization_compass import graphs

    g = graphs.build('compass', {'method': TOY})
    names = {n.name for n in g.nodes}
    assert names == {f'heading_estimator_{TOY}', f'tilt_corrector_{TOY}'}
    g = graphs.build('compass', {'method': TOY_TILT})
    assert {n.name for n in g.nodes} == {
        f'heading_estimator_{TOY_TILT}'
    }  # reads the tilt: no corrector
    est = [n for n in g.nodes if n.name == f'heading_estimator_{TOY_TILT}'][0]
    assert any('imu' in t for t, _ in est.subscribes)
    g = graphs.sim_graph(methods=('zenith', TOY), tilt_aware=True)
    names = {n.name for n in g.nodes}
    assert {f'heading_estimator_{m}' for m in ('zenith', TOY, 'tilt_aware', TOY_TILT)} <= names
    assert {f'tilt_corrector_{m}' for m in ('zenith', TOY)} <= names
    assert not {f'tilt_corrector_{m}' for m in ('tilt_aware', TOY_TILT)} & names
    ev = [n for n in g.nodes if n.name == 'error_evaluator'][0]
    assert ev.parameters['direct_methods'] == ['tilt_aware', TOY_TILT]


@pytest.fixture
def toy_map(toys):
    from polarization_compass.sweep import run_sweep, SweepSpec

    spec = SweepSpec([TOY, 'zenith'], [30.0], [-20.0, 0.0, 20.0], [0.0], [0.0])
    assert spec.knobs[TOY] == {'stride': 7}  # the class's declared sampling
    return run_sweep(spec, workers=1, progress=False)


def test_toy_in_an_error_map_sweep(toy_map):
    m = toy_map
    i = m.method_index(TOY)
    assert m.meta['sampling'][TOY]['knobs'] == {'stride': 7}
    err = np.asarray(m.error_deg)[i].reshape(-1)
    np.testing.assert_allclose(
        err, [7.0 + 20.0, 7.0, 7.0 - 20.0], atol=1e-9
    )  # psi 7 at yaw -20, 0, 20
    assert np.all(m.valid[i])


def test_toy_in_the_figures(toy_map):
    import matplotlib.pyplot as plt
    from polarization_compass.figures import draw_figure

    fig = draw_figure(toy_map, 'fig9', methods=[TOY, 'zenith'], pitch=0.0, sun_altitude=30.0)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    toy = lines['Toy constant']
    assert (toy.get_color(), toy.get_linestyle()) == ('tab:brown', '--')
    assert lines['Zenith'].get_color() == 'tab:blue'
    plt.close(fig)


def test_toy_in_the_replay(toys, tmp_path):
    from polarization_compass.recording import record_sim, RecordSpec
    from polarization_compass.replay import method_groups, replay_bag, ReplayConfig
    from polarization_compass.scene import load_scene

    # cost: the toy (100) outweighs every built-in together, the tilt toy (0.01) joins the lightest
    # group
    groups = method_groups(list(BUILTIN) + [TOY, TOY_TILT], 2)
    assert [TOY] in groups
    assert method_groups([TOY, TOY_TILT, 'zenith'], 2) == [[TOY], [TOY_TILT, 'zenith']]

    cam = CameraModel(
        width_px=96,
        height_px=80,
        focal_length_mm=4.0,
        pixel_pitch_x_um=2448 * 3.45 / 96,
        pixel_pitch_y_um=2048 * 3.45 / 80,
    )
    scene = load_scene(None).replace(camera=cam)
    bag = record_sim(scene, RecordSpec(duration_s=0.5, rate_hz=10.0), tmp_path / 'bag')['bag']
    # the toys' constant psi is not the scene's heading: the IMU-prior check, which replay applies
    # as the node does, would decline it (prior_disagrees); this test is about the registry
    cfg = ReplayConfig(methods=(TOY, TOY_TILT), knobs={'*': {'stride': 3}}, prior_source='none')
    res = replay_bag(bag, cfg, workers=2)
    assert res.frames >= 4
    for name in (TOY, TOY_TILT):
        rows = [r for r in res.rows if r.method == name]
        assert len(rows) == res.frames
        assert all(r.status == 'ok' for r in rows), [(r.status, r.reason) for r in rows]
    # psi = 3 deg (the shared stride knob reached the toy): raw bearing = 3 + the sun's azimuth at
    # the stamp
    from polarization_compass.solar import sun_position

    site = scene.site
    for r in (r for r in res.rows if r.method == TOY):
        az = float(
            sun_position(
                np.datetime64(r.stamp_ns, 'ns'),
                site.latitude_deg,
                site.longitude_deg,
                site.altitude_m,
            ).azimuth_deg
        )
        assert abs(cv.wrap_180_deg(r.raw_bearing_deg - (3.0 + az))) < 1e-3
    assert TOY_TILT in ReplayConfig().direct_methods


def test_toy_in_the_bench(toys):
    """The benchmark sweeps a new method's declared knobs and draws it in its registry colour."""
    from bench import report
    from bench.accuracy import condition_methods, CONDITIONS, knob_sets
    from bench.report import accuracy as report_accuracy
    from bench.report import formatting, speed

    # the toy declares one knob, stride: strided sets only (no window, region or disc sets)
    assert knob_sets(TOY, 'quick', False) == [
        ('stride 4', {'stride': 4}, None),
        ('stride 16', {'stride': 16}, None),
    ]
    full = knob_sets(TOY, 'full', True)
    assert [label for label, _, _ in full] == [
        'default, superpixel demosaic',
        'stride 4, superpixel demosaic',
        'stride 8, superpixel demosaic',
        'stride 16, superpixel demosaic',
        'default, full-res demosaic',
        'stride 2, full-res demosaic',
        'stride 4, full-res demosaic',
        'stride 8, full-res demosaic',
        'stride 16, full-res demosaic',
    ]
    for _, knobs, _ in full:
        assert make_estimator(TOY, **knobs).knobs['stride'] == knobs.get('stride', 1)
    # the tilt toy reads the tilt: it runs where tilt_aware runs, the toy where the others do
    everyone = registry.names()
    level = [m for m in BUILTIN if m != 'tilt_aware'] + [TOY]
    assert condition_methods(CONDITIONS['tilted'], everyone) == level
    assert condition_methods(CONDITIONS['tilted_tilt_aware'], everyone) == ['tilt_aware', TOY_TILT]
    assert condition_methods(CONDITIONS['ideal_level'], everyone) == [*BUILTIN, TOY, TOY_TILT]
    # colours and order of the plots, labels of the tables: from the class facts
    assert report.method_colour(TOY) == 'tab:brown'
    assert report.method_colour(TOY_TILT) == 'tab:olive'
    assert report.method_colour('zenith') == 'tab:blue' and report.method_colour('gone') == 'k'
    ranked = sorted([TOY, 'gone', 'zenith', TOY_TILT, 'tilt_aware'], key=formatting.method_rank)
    assert ranked == ['zenith', 'tilt_aware', TOY, TOY_TILT, 'gone']
    assert speed.knobs_label(TOY, {'stride': 8}) == 'stride 8'
    assert speed.knobs_label('zenith', {'window_px': 33}) == 'window 33 px'
    cells = [
        {'method': TOY, 'condition': 'ideal_level', 'knobs_label': label}
        for label in ('stride 4', 'stride 8')
    ]
    assert report_accuracy.reference_cell(cells, TOY, 'ideal_level') is cells[1]
