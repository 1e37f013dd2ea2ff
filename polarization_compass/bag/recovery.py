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
Damaged-bag recovery: a truncated storage file read up to the damage, a damaged chunk skipped.

An MCAP file cut short is read with rosbags' own MCAP reader up to its last complete record; a
truncated sqlite3 file through a copy whose header counts the pages present. In an indexed MCAP
file a chunk that fails its CRC (or cannot be decompressed) is skipped and the next chunks are read
(:func:`_skip_damaged_chunks`).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from .errors import BagError

__all__: list[str] = []  # private helpers of bag.reader


class _RecoveredConnection:
    """A connection of a recovered storage file (what rosbags' readers expose)."""

    def __init__(self, cid, topic, msgtype, msgcount):
        self.id, self.topic, self.msgtype, self.msgcount = cid, topic, msgtype, msgcount


class _RecoveredMcap:
    """
    An MCAP file cut short, read up to its last complete record.

    The file (a killed recorder, a copy that stopped) is read with rosbags' own MCAP reader: the
    reader gets the intact prefix followed by a footer that announces no summary, so it scans the
    records (``McapReader.meta_scan``/``messages_scan``, as for an unindexed file) instead of
    refusing the missing footer (``File end magic is invalid``).
    """

    _MAGIC = b'\x89MCAP0\r\n'

    def __init__(self, path: Path, why: str):
        import struct

        from rosbags.rosbag2.storage_mcap import McapReader

        self.path = path
        size = path.stat().st_size
        with open(path, 'rb') as fh:
            head = fh.read(8)
            if head != self._MAGIC:
                raise BagError(f'{path.name}: not an MCAP file')
            pos = 8
            good = None
            while pos + 9 <= size:  # records: opcode (1), length (8), body
                fh.seek(pos)
                op, n = struct.unpack('<BQ', fh.read(9))
                end = pos + 9 + n
                if end > size or op == 0x0F and n == 0:
                    break
                if op in (
                    0x02,
                    0x0E,
                    0x0F,
                ):  # footer, summary offset, data end: the data ends here
                    break
                good = end
                pos = end
        if good is None:
            raise BagError(f'{path.name}: no complete MCAP record')
        self.discarded_bytes = size - good
        footer = bytes([0x02]) + struct.pack('<QQQI', 20, 0, 0, 0) + self._MAGIC
        self._bio = _PrefixWithTail(path, good, footer)
        self._mcap = McapReader(path)
        self._mcap.bio = self._bio
        try:
            self._mcap._open()  # rosbags' own reader; scans (no index)
        except BaseException:
            self._bio.close()
            raise
        if not self._mcap.connections or not self._mcap.metadata.message_count:
            self._bio.close()
            raise BagError(f'{path.name}: nothing readable before the damage')
        self.connections = [
            _RecoveredConnection(c.id, c.topic, c.msgtype, c.msgcount)
            for c in self._mcap.connections
        ]
        self._by_id = {c.id: c for c in self._mcap.connections}
        self.message_count = int(self._mcap.metadata.message_count)
        self.duration = int(self._mcap.metadata.duration)
        self.announced = _announced_counts(path.parent)
        self.note = (
            f"{why}; read with rosbags' MCAP reader up to the last complete record "
            f'({self.message_count} messages; {self.discarded_bytes} bytes at the end discarded)'
        )

    def messages(self, connections):
        conns = [self._by_id[c.id] for c in connections]
        for c, t, raw in self._mcap.messages(conns):
            yield c, t, raw

    def close(self):
        self._bio.close()


class _PrefixWithTail:
    """A read-only file object: the first ``n`` bytes of ``path`` followed by ``tail`` (footer)."""

    def __init__(self, path: Path, n: int, tail: bytes):
        self._fh = open(path, 'rb')
        self._n, self._tail, self._pos = int(n), bytes(tail), 0

    def seek(self, off: int, whence: int = 0) -> int:
        size = self._n + len(self._tail)
        self._pos = max(0, {0: off, 1: self._pos + off, 2: size + off}[whence])
        return self._pos

    def tell(self) -> int:
        return self._pos

    def read(self, k: int = -1) -> bytes:
        size = self._n + len(self._tail)
        k = size - self._pos if k is None or k < 0 else min(k, size - self._pos)
        out = b''
        if self._pos < self._n and k > 0:
            self._fh.seek(self._pos)
            out = self._fh.read(min(k, self._n - self._pos))
        rest = k - len(out)
        if rest > 0:
            start = self._pos + len(out) - self._n
            out += self._tail[start : start + rest]
        self._pos += len(out)
        return out

    def close(self) -> None:
        self._fh.close()


class _RecoveredSqlite:
    """
    A truncated rosbag2 sqlite3 file read with Python's sqlite3.

    Not with rosbags' reader: it counts every topic's messages when it opens, which fails on the
    first missing page. What is read is a temporary copy whose header page count is set to the
    pages present, in insertion order (rowid) until the first missing page.
    """

    def __init__(self, path: Path, why: str):
        import shutil
        import sqlite3
        import struct
        import tempfile

        self.path = path
        self._tmp = tempfile.TemporaryDirectory(prefix='pc_bag_recover_')
        copy = Path(self._tmp.name) / path.name
        shutil.copyfile(path, copy)
        with open(copy, 'r+b') as fh:
            hdr = fh.read(100)
            if not hdr.startswith(b'SQLite format 3\x00'):
                raise BagError(f'{path.name}: not an SQLite file')
            page = struct.unpack('>H', hdr[16:18])[0]
            page = 65536 if page == 1 else page
            pages = copy.stat().st_size // page
            fh.truncate(pages * page)
            fh.seek(28)
            fh.write(struct.pack('>I', pages))
        self._db = sqlite3.connect(f'file:{copy}?mode=ro', uri=True, check_same_thread=False)
        rows = self._db.execute('SELECT id, name, type FROM topics ORDER BY id').fetchall()
        counts: Counter = Counter()
        try:  # what is readable (topic ids only: no message data is read)
            for (cid,) in self._db.execute('SELECT topic_id FROM messages ORDER BY id'):
                counts[cid] += 1
        except sqlite3.DatabaseError:
            pass
        self.connections = [
            _RecoveredConnection(i, name, mtype, counts[i]) for i, name, mtype in rows
        ]
        self.message_count = sum(counts.values())
        if not self.message_count:
            self.close()
            raise BagError(f'{path.name}: nothing readable before the damage')
        self.duration = 0
        self.announced = _announced_counts(path.parent)
        self.note = (
            f"{why}; read with Python's sqlite3 from a copy whose header counts the pages "
            'present, '
            'in recording order up to the first missing page'
        )

    def messages(self, connections):
        by_id = {c.id: c for c in connections}
        for cid, t, data in self._db.execute(
            'SELECT topic_id, timestamp, data FROM messages ORDER BY id'
        ):
            c = by_id.get(cid)
            if c is not None:
                yield c, int(t), data

    def close(self):
        try:
            self._db.close()
        finally:
            self._tmp.cleanup()


class _ChunkSkippingMessages:
    """
    ``McapReader.messages`` of one indexed MCAP storage, a damaged chunk skipped.

    rosbags merges one generator per chunk of the summary's chunk index (``msgsrc``); a chunk
    whose CRC or decompression fails raises, which ended the whole merge, so every later chunk was
    lost too. Here each chunk's generator ends at its damage instead (a chunk is decompressed and
    checked whole before any of its messages is yielded, so a damaged chunk yields none) and
    ``on_damage(where, exc)`` is told (``where``: the file and the chunk's byte offset). An
    unindexed file keeps rosbags' scan.
    """

    def __init__(self, storage, on_damage):
        self.storage, self.on_damage = storage, on_damage

    def __call__(self, connections, start=None, stop=None):
        import heapq

        from rosbags.rosbag2.storage_mcap import McapReader, msgsrc

        st = self.storage
        if not st.chunks:
            yield from McapReader.messages(st, connections, start, stop)
            return
        channel_map = {conn.id: conn for conn in connections}
        chunks = [
            self._checked(
                msgsrc(
                    x,
                    channel_map,
                    x.message_start_time if start is None else start,
                    x.message_end_time + 1 if stop is None else stop,
                    st.bio,
                ),
                x.chunk_start_offset,
            )
            for x in st.chunks
            if (start is None or start < x.message_end_time + 1)
            and (stop is None or x.message_start_time < stop)
            and (any(x.channel_count.get(cid, 0) for cid in channel_map))
        ]
        for timestamp, offset, connection, data in heapq.merge(*chunks):
            if offset:  # (0: a chunk's start marker)
                yield connection, timestamp, data

    def _checked(self, source, offset: int):
        try:
            yield from source
        except Exception as exc:  # noqa: BLE001 - CRC, decompression, a cut record: damage
            self.on_damage(f'{self.storage.path.name} byte {offset}', exc)


def _skip_damaged_chunks(reader, on_damage) -> None:
    """
    Make every indexed MCAP storage of an open rosbags ``Reader`` skip its damaged chunks.

    Parameters
    ----------
    reader : rosbags.rosbag2.Reader
        The open reader (its ``storages``).
    on_damage : callable
        ``on_damage(where, exception)`` for each damaged chunk met while reading (``where``: the
        storage file's name and the chunk's byte offset).

    """
    from rosbags.rosbag2.storage_mcap import McapReader

    directory = getattr(reader, 'storage', reader)  # rosbags' DirectoryReader behind Reader
    for storage in getattr(directory, 'storages', None) or getattr(reader, 'storages', ()):
        if isinstance(storage, McapReader):
            storage.messages = _ChunkSkippingMessages(storage, on_damage)


def _announced_counts(directory: Path) -> dict | None:
    """{topic: message count} from a rosbag2 metadata.yaml, or None when absent or unreadable."""
    from ..safe_load import load_yaml, read_text

    try:
        d = load_yaml(
            read_text(directory / 'metadata.yaml', BagError, 'bag metadata'), 'metadata', BagError
        )
        info = d['rosbag2_bagfile_information']
        return {
            t['topic_metadata']['name']: int(t['message_count'])
            for t in info['topics_with_message_count']
        }
    except (BagError, KeyError, TypeError, ValueError):
        return None


def _recovered_storage(path: Path, why: str):
    """
    Open a damaged bag's single storage file up to the damage.

    Through :class:`_RecoveredMcap` or :class:`_RecoveredSqlite`; raises when that fails too.
    """
    return (_RecoveredMcap if path.suffix == '.mcap' else _RecoveredSqlite)(path, why)
