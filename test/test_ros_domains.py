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
The ROS domain ids conftest hands out: disjoint between pytest-xdist workers, never the run's.

Two tests that run at once on two workers must never share a domain (a graph would hear the
other's frames), and no test graph may use a worker's own ROS_DOMAIN_ID (its in-process nodes).
"""

import os

from conftest import next_ros_domain, parse_domains, worker_domains
import pytest


def test_a_pool_is_read_in_the_order_written_without_repeats():
    assert parse_domains('118-121') == [118, 119, 120, 121]
    assert parse_domains(' 5, 1-3 ,2,232') == [5, 1, 2, 3, 232]


@pytest.mark.parametrize('bad', ['', '7-', 'a-b', '3-1', '230-233', '1,,2'])
def test_a_bad_pool_is_a_usage_error(bad):
    with pytest.raises(pytest.UsageError):
        parse_domains(bad)


@pytest.mark.parametrize('count', [1, 2, 3, 4, 11])
def test_every_worker_gets_a_slice_of_its_own(count):
    pool = parse_domains('118-140')
    slices = [worker_domains(pool, f'gw{i}', count) for i in range(count)]
    assert all(len(s) >= 2 for s in slices)
    taken = [d for s in slices for d in s]
    assert len(taken) == len(set(taken)) and set(taken) <= set(pool)
    assert worker_domains(pool, '', 1) == pool  # without xdist: the whole pool


def test_too_small_a_pool_for_the_workers_is_a_usage_error():
    with pytest.raises(pytest.UsageError, match='two at least'):
        worker_domains(parse_domains('118-140'), 'gw0', 12)


def test_a_test_graph_gets_a_domain_of_its_own_never_the_workers_and_the_next_ones_differ(
    ros_env, ros_domain
):
    own = int(os.environ['ROS_DOMAIN_ID'])  # this worker's: its in-process nodes
    assert int(ros_env['ROS_DOMAIN_ID']) == ros_domain != own
    cycle = [next_ros_domain()]
    while cycle[-1] != ros_domain and len(cycle) <= 233:
        cycle.append(next_ros_domain())
    # the worker's other ids in turn: the next test graph is never in this one's domain
    assert cycle[-1] == ros_domain and len(set(cycle)) == len(cycle) and own not in cycle
    pool = parse_domains(os.environ.get('POLARIZATION_COMPASS_TEST_DOMAINS', '1-100'))
    assert set(cycle) <= set(pool)
    if 'PYTEST_XDIST_WORKER' in os.environ:
        assert own in pool
