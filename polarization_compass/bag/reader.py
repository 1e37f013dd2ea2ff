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
Reading a rosbag2 with per-topic skip accounting.

:class:`BagReader` yields raw messages in receive-time order and says what a damaged bag lost;
:class:`Tally` counts per topic what was read, used and skipped (by reason).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from .errors import _one_line, BagError
from .recovery import _recovered_storage, _skip_damaged_chunks

__all__ = [
    'Tally',
    'BagReader',
]


# --------------------------------------------------------------------------------------------
# Skip accounting
# --------------------------------------------------------------------------------------------
class Tally:
    """
    Count per topic the messages read, used, and skipped by reason.

    Nothing leaves a bag unaccounted: for every topic, ``read == used + sum(skipped)`` once a
    replay finishes (:meth:`balanced`). ``read`` and ``used`` are :class:`collections.Counter`
    objects by topic that callers increment.
    """

    def __init__(self):
        self.read: Counter = Counter()
        self.used: Counter = Counter()
        self.skipped: Counter = Counter()  # (topic, reason) -> n
        self.notes: Counter = Counter()  # (topic, note) -> n, not skips (e.g. out_of_order)
        self.examples: dict = {}  # (topic, reason) -> first detail message

    def skip(self, topic: str, reason: str, detail: str = '') -> None:
        """
        Count one skipped message of ``topic``.

        Parameters
        ----------
        topic : str
            Topic name.
        reason : str
            Short tag, e.g. ``"bad_cdr"`` (a :class:`MessageError`'s ``reason``).
        detail : str, default ""
            Message of the first skip for this topic and reason, kept as an example.

        """
        self.skipped[(topic, reason)] += 1
        self.examples.setdefault((topic, reason), detail)

    def note(self, topic: str, what: str) -> None:
        """
        Count one event of ``topic`` that is not a skip (e.g. ``out_of_order``).

        Parameters
        ----------
        topic : str
            Topic name.
        what : str
            Short tag of the event.

        """
        self.notes[(topic, what)] += 1

    def skipped_total(self, topic: str | None = None) -> int:
        """
        Return the number of skipped messages.

        Parameters
        ----------
        topic : str, optional
            Count this topic only; None counts all topics.

        Returns
        -------
        int
            Skips over all reasons.

        """
        return sum(n for (t, _), n in self.skipped.items() if topic is None or t == topic)

    def balanced(self) -> bool:
        """
        Return whether every topic's read count equals used plus skipped.

        Returns
        -------
        bool
            True when no message is unaccounted.

        """
        return all(self.read[t] == self.used[t] + self.skipped_total(t) for t in self.read)

    def to_dict(self) -> dict:
        """
        Return the counts as plain data, by topic.

        Returns
        -------
        dict
            ``{topic: {"read", "used", "skipped": {reason: n}, "notes": {what: n}[, "first_reason":
            {reason: detail}]}}``, topics sorted.

        """
        topics = sorted(set(self.read) | {t for t, _ in self.skipped} | {t for t, _ in self.notes})
        out = {}
        for t in topics:
            out[t] = {
                'read': self.read[t],
                'used': self.used[t],
                'skipped': {r: n for (tt, r), n in sorted(self.skipped.items()) if tt == t},
                'notes': {r: n for (tt, r), n in sorted(self.notes.items()) if tt == t},
            }
            ex = {
                r: self.examples[(tt, r)]
                for (tt, r) in self.skipped
                if tt == t and self.examples.get((tt, r))
            }
            if ex:
                out[t]['first_reason'] = ex
        return out

    def lines(self) -> list[str]:
        """
        Return a human-readable summary, one line per topic.

        Returns
        -------
        list of str
            E.g. ``"/imu/data: read 10, used 9, skipped: bad_cdr 1"``.

        """
        out = []
        for t, d in self.to_dict().items():
            s = ', '.join(f'{r} {n}' for r, n in d['skipped'].items()) or 'none'
            extra = (
                '; ' + ', '.join(f'{r} {n}' for r, n in d['notes'].items()) if d['notes'] else ''
            )
            out.append(f'{t}: read {d["read"]}, used {d["used"]}, skipped: {s}{extra}')
        return out


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
class BagReader:
    """
    A rosbag2 (directory with metadata.yaml; MCAP or sqlite3) opened for reading.

    ``BagReader(path)`` raises :class:`BagError` with one line if the path is not a readable bag.
    Use as a context manager. :meth:`messages` yields ``(topic, msgtype, log_time_ns, raw_cdr)``
    in the bag's receive-time order for the topics asked.
    """

    def __init__(self, path):
        from rosbags.rosbag2 import Reader

        p = Path(path)
        if not p.exists():
            raise BagError(f'bag {str(p)!r} does not exist')
        if p.is_file() and p.suffix == '.mcap' and not (p.parent / 'metadata.yaml').exists():
            raise BagError(
                f'{str(p)!r} is a bare MCAP file; give the rosbag2 directory (with '
                'metadata.yaml), '
                'or run `ros2 bag reindex` on its directory'
            )
        if p.is_file() and (p.parent / 'metadata.yaml').exists():
            p = p.parent
        if not p.is_dir():
            raise BagError(
                f'{str(p)!r} is not a rosbag2 directory (a directory with metadata.yaml)'
            )
        self.path = p
        self.damage: str | None = None  # what went wrong reading, once the bag is read (one line)
        self.recovered: str | None = None  # how a damaged bag was opened (one line), or None
        self._read_counts: Counter = Counter()  # messages yielded per topic
        storage = sorted(x for x in p.iterdir() if x.suffix in ('.mcap', '.db3') and x.is_file())
        if (p / 'metadata.yaml').exists() or (p / 'metadata.yaml').is_symlink():
            from ..safe_load import (
                regular_file,  # not a FIFO or /dev/zero (rosbags would read it forever)
            )

            regular_file(p / 'metadata.yaml', BagError, 'bag metadata', max_bytes=16 << 20)
        if not (p / 'metadata.yaml').is_file():
            if len(storage) != 1:
                raise BagError(f'{str(p)!r} is not a rosbag2 directory: it has no metadata.yaml')
            # a recorder killed before it wrote metadata.yaml: read its one storage file up to the
            # damage
            self._reader = _recovered_storage(
                storage[0], 'no metadata.yaml (a recorder killed before the end)'
            )
            self.recovered = self._reader.note
            return
        self._damaged_chunks: dict = {}  # {"file byte offset": why}: skipped, each noted once
        try:
            self._reader = Reader(p)
            self._reader.open()
            _skip_damaged_chunks(self._reader, self._chunk_damaged)
        except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad bag
            first = f'{str(p)!r} is not a readable rosbag2: {_one_line(exc)}'
            if len(storage) != 1:
                raise BagError(first) from None
            try:
                self._reader = _recovered_storage(storage[0], _one_line(exc))
            except Exception:  # noqa: BLE001 - not recoverable either: the first error says why
                raise BagError(first) from None
            self.recovered = self._reader.note

    def _chunk_damaged(self, where: str, exc: Exception) -> None:
        """Note a damaged MCAP chunk (skipped; the next chunks are read), once per chunk."""
        self._damaged_chunks.setdefault(where, _one_line(exc))
        n = len(self._damaged_chunks)
        where = '; '.join(f'{w}: {why}' for w, why in self._damaged_chunks.items())
        self.damage = (
            f'{n} damaged MCAP chunk{"s" if n > 1 else ""} skipped, the rest read ({where})'
        )

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the bag; errors while closing a half-broken bag are ignored."""
        try:
            self._reader.close()
        except Exception:  # noqa: BLE001 - closing a half-broken bag must not mask the real error
            pass

    @property
    def duration_s(self) -> float:
        """Time between the first and the last message [s] (0 for an empty bag)."""
        return self._reader.duration / 1e9 if self._reader.message_count else 0.0

    @property
    def message_count(self) -> int:
        """Return the number of messages in the bag, all topics."""
        return int(self._reader.message_count)

    def topic_types(self) -> dict:
        """
        Return each topic's message types and counts over all connections.

        Returns
        -------
        dict
            ``{topic: {msgtype: message count}}`` (a topic recorded from publishers of different
            types has one connection per type).

        """
        out: dict = {}
        for c in self._reader.connections:
            types = out.setdefault(c.topic, {})
            types[c.msgtype] = types.get(c.msgtype, 0) + int(c.msgcount)
        return out

    def topics(self) -> dict:
        """
        Return the topics of the bag with their types and message counts.

        Returns
        -------
        dict
            ``{topic: (msgtype, message count)}`` over all connections (types joined by ``|``
            when a topic has several).

        """
        out: dict = {}
        for c in self._reader.connections:
            t, n = out.get(c.topic, (c.msgtype, 0))
            if t != c.msgtype:
                t = f'{t}|{c.msgtype}'
            out[c.topic] = (t, n + int(c.msgcount))
        return out

    def messages(self, topics):
        """
        Yield the messages of the given topics in receive-time order.

        Parameters
        ----------
        topics : iterable of str
            Topic names; unknown ones are ignored.

        Yields
        ------
        tuple
            ``(topic, msgtype, log_time_ns, raw)``: receive time [ns], raw CDR bytes.

        Raises
        ------
        BagError
            A storage-level failure part-way (truncated file, bad chunk), naming the bag.

        """
        conns = [c for c in self._reader.connections if c.topic in set(topics)]
        if not conns:
            return
        self._requested = getattr(self, '_requested', set()) | {c.topic for c in conns}
        try:
            for c, t, raw in self._reader.messages(connections=conns):
                self._read_counts[c.topic] += 1
                yield c.topic, c.msgtype, int(t), raw
        except BagError:
            raise
        # damage part-way: what was read stands, the rest is counted lost
        except Exception as exc:  # noqa: BLE001
            self.damage = f'reading stopped part-way ({_one_line(exc)})'

    def lost(self) -> dict:
        """
        Return the messages the bag's index announces that were not read (a damaged bag).

        Returns
        -------
        dict
            ``{topic: count}`` for the topics read by :meth:`messages`; empty when everything
            announced was read or nothing is announced.

        """
        expected = {c.topic: 0 for c in self._reader.connections}
        for c in self._reader.connections:
            expected[c.topic] += int(getattr(c, 'msgcount', 0) or 0)
        announced = getattr(self._reader, 'announced', None) or expected
        asked = getattr(self, '_requested', set())
        return {
            t: n - self._read_counts.get(t, 0)
            for t, n in announced.items()
            if n > self._read_counts.get(t, 0) and t in asked
        }

    def damage_notes(self) -> list[str]:
        """
        Return one-line statements of damage found while opening or reading.

        Returns
        -------
        list of str
            Empty for a sound bag; else how it was read and the messages lost per topic.

        """
        notes = []
        if self.recovered:
            notes.append(f'damaged bag: {self.recovered}')
        if self.damage:
            notes.append(f'damaged bag: {self.damage}')
        lost = self.lost() if (self.recovered or self.damage) else {}
        if lost:
            notes.append(
                'messages lost to the damage: '
                + ', '.join(f'{t} {n}' for t, n in sorted(lost.items()))
            )
        elif self.recovered or self.damage:
            notes.append(
                'messages lost to the damage: unknown (the bag has no index of what it held)'
            )
        return notes
