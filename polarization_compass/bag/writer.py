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
Writing a rosbag2 with rosbags, one connection per role of a topic map.

rosbags writes MCAP chunks without their CRC (0: "not available"), so a reader cannot notice damage
to the data; :func:`fill_mcap_chunk_crcs` adds them when the bag is closed, as ``ros2 bag record``
writes them, and rosbags' reader then verifies each chunk it reads.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from .codec import typestore
from .errors import BagError
from .topic_map import default_topic_map, TopicMap

__all__ = [
    'BagWriter',
    'fill_mcap_chunk_crcs',
]

_MCAP_MAGIC = b'\x89MCAP0\r\n'
_OP_CHUNK, _OP_DATA_END = 0x06, 0x0F


def fill_mcap_chunk_crcs(path) -> int:
    """
    Write the CRC of every uncompressed chunk whose CRC field is 0, in place.

    MCAP chunk record body: message start and end time (uint64 each), uncompressed size (uint64),
    uncompressed CRC (uint32: CRC-32 of the records, 0 = not available), compression (uint32
    length + string), records size (uint64), records [1]_. Only chunks with no compression are
    filled (their records are the uncompressed bytes); the file is scanned up to the data end.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file.

    Returns
    -------
    int
        The number of chunks whose CRC was written.

    References
    ----------
    .. [1] MCAP file format specification, "Chunk" (op 0x06), https://mcap.dev/spec

    """
    import struct
    import zlib

    filled = 0
    with open(path, 'r+b') as fh:
        if fh.read(8) != _MCAP_MAGIC:
            return 0
        while True:
            head = fh.read(9)
            if len(head) < 9:
                return filled
            op, length = struct.unpack('<BQ', head)
            body_at = fh.tell()
            if op == _OP_DATA_END:
                return filled
            if op == _OP_CHUNK:
                _, _, size, crc, n = struct.unpack('<QQQII', fh.read(32))
                compression = fh.read(n)
                (records_size,) = struct.unpack('<Q', fh.read(8))
                if crc == 0 and compression == b'' and records_size == size:
                    crc = zlib.crc32(fh.read(size))  # the records follow the size field
                    fh.seek(body_at + 24)
                    fh.write(struct.pack('<I', crc))
                    filled += 1
            fh.seek(body_at + length)


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
        """Close the bag (writes its metadata and MCAP chunk CRCs); closing twice is harmless."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
            for f in self.path.glob('*.mcap'):
                fill_mcap_chunk_crcs(f)

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
