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

"""Writing a rosbag2 with rosbags, one connection per role of a topic map."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from .codec import typestore
from .errors import BagError
from .topic_map import default_topic_map, TopicMap

__all__ = [
    'BagWriter',
]


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
class BagWriter:
    """
    Write a rosbag2 with rosbags; one connection per role.

    ``write(role, msg, log_time_ns)`` serialises a rosbags message; ``write_raw`` stores bytes as
    they are (tests use it to plant corrupt messages). Use as a context manager.

    Parameters
    ----------
    path : str or os.PathLike
        The bag directory to create; it must not exist (rosbag2 refuses to overwrite) and its
        parent must.
    topic_map : TopicMap, optional
        Topics and types of the roles; default :func:`default_topic_map`.
    storage : {"mcap", "sqlite3"}, default "mcap"
        Storage plugin.
    extra_topics : dict, optional
        ``{topic: msgtype}`` of further connections, written under the topic name as role.

    Raises
    ------
    BagError
        The path exists, its directory does not, or the storage is unknown.

    """

    def __init__(
        self, path, topic_map: TopicMap | None = None, storage: str = 'mcap', extra_topics=None
    ):
        from rosbags.rosbag2 import StoragePlugin, Writer

        p = Path(path)
        if p.exists():
            raise BagError(f'output {str(p)!r} already exists; rosbag2 does not overwrite bags')
        if not p.parent.is_dir():
            raise BagError(f'directory {str(p.parent)!r} for the output bag does not exist')
        plugins = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
        if storage not in plugins:
            raise BagError(f"storage must be 'mcap' or 'sqlite3', got {storage!r}")
        self.path = p
        self.topic_map = topic_map or default_topic_map()
        self._writer = Writer(p, version=9, storage_plugin=plugins[storage])
        self._writer.open()
        self._conns = {}
        ts = typestore()
        for role, spec in self.topic_map.topics.items():
            self._conns[role] = self._writer.add_connection(spec.topic, spec.type, typestore=ts)
        for topic, mtype in (extra_topics or {}).items():
            self._conns[topic] = self._writer.add_connection(topic, mtype, typestore=ts)
        self.counts: Counter = Counter()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the bag (writes its metadata); closing twice is harmless."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def write(self, role: str, msg, log_time_ns: int) -> None:
        """
        Serialise and write one message.

        Parameters
        ----------
        role : str
            A role of the topic map, or a topic of ``extra_topics``.
        msg : object
            A rosbags message of that connection's type.
        log_time_ns : int
            Receive time [ns since the Unix epoch] (the bag's order).

        """
        raw = typestore().serialize_cdr(msg, self._conns[role].msgtype)
        self.write_raw(role, raw, log_time_ns)

    def write_raw(self, role: str, raw: bytes, log_time_ns: int) -> None:
        """
        Write bytes as they are (no serialisation), e.g. a planted corrupt message.

        Parameters
        ----------
        role : str
            A role of the topic map, or a topic of ``extra_topics``.
        raw : bytes
            The CDR payload.
        log_time_ns : int
            Receive time [ns since the Unix epoch].

        """
        self._writer.write(self._conns[role], int(log_time_ns), raw)
        self.counts[role] += 1
