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
MCAP chunk CRCs (issue 24): random bytes over one image are a damage note, never a used frame.

rosbags writes chunks with CRC 0 ("not available"), so damage to a bag written here went unseen
(replay gave ``ok`` 149 deg off). The writer now fills the CRCs, checked here with zlib against the
records as the MCAP specification lays them out, and the reader reports the damaged chunk, skips
it and reads the chunks after it (it used to stop there, the rest of the bag counted lost).
"""

import os
import struct
import zlib

import numpy as np
from polarization_compass import bag as B

IMAGE_BYTES = 1_500_000  # more than rosbags' 1 MiB chunk: one image per chunk


def _chunks(path):
    """Return (crc offset, stored crc, crc32 of the records, records offset, size) per chunk."""
    out = []
    data = path.read_bytes()
    pos = 8
    while pos + 9 <= len(data):
        op, n = struct.unpack_from('<BQ', data, pos)
        body = pos + 9
        if op == 0x0F:
            break
        if op == 0x06:
            _, _, size, crc, clen = struct.unpack_from('<QQQII', data, body)
            rec = body + 32 + clen + 8
            out.append((body + 24, crc, zlib.crc32(data[rec : rec + size]), rec, size))
        pos = body + n
    return out


def _bag(tmp_path, n=3):
    rng = np.random.default_rng(0)
    path = tmp_path / 'run'
    with B.BagWriter(path) as w:
        for k in range(n):
            w.write_raw('image', rng.bytes(IMAGE_BYTES), (k + 1) * 10**9)
    return path, next(path.glob('*.mcap'))


def test_the_writer_fills_every_chunk_crc(tmp_path):
    _, mcap = _bag(tmp_path)
    chunks = _chunks(mcap)
    assert len(chunks) >= 3
    assert all(stored == computed != 0 for _, stored, computed, _, _ in chunks)


def test_random_bytes_over_one_image_are_damage_not_data(tmp_path):
    """One damaged chunk in the middle: every frame of the other chunks, the damage noted once."""
    path, mcap = _bag(tmp_path, n=5)
    with B.BagReader(path) as r:
        intact = [(t, raw) for _, _, t, raw in r.messages(['/camera/image_raw'])]
    assert len(intact) == 5 and not r.damage_notes()
    chunks = _chunks(mcap)
    assert len(chunks) == 5  # one image per chunk
    _, _, _, rec, size = chunks[2]
    with open(mcap, 'r+b') as fh:
        fh.seek(rec + size // 4)
        fh.write(os.urandom(size // 2))
    with B.BagReader(path) as r:
        got = [(t, raw) for _, _, t, raw in r.messages(['/camera/image_raw'])]
        lost = r.lost()
        again = [(t, raw) for _, _, t, raw in r.messages(['/camera/image_raw'])]  # a 2nd pass
        notes = r.damage_notes()
    assert got == intact[:2] + intact[3:]  # the damaged image is never yielded, the rest is
    assert again == got
    damage = [n for n in notes if 'checksum' in n]
    assert len(damage) == 1 and '1 damaged MCAP chunk skipped' in damage[0], notes
    assert lost == {'/camera/image_raw': 1}


def test_two_damaged_chunks_are_both_skipped_and_named(tmp_path):
    path, mcap = _bag(tmp_path, n=5)
    for _, _, _, rec, size in (_chunks(mcap)[0], _chunks(mcap)[3]):
        with open(mcap, 'r+b') as fh:
            fh.seek(rec + size // 2)
            fh.write(b'\x00' * 64 if fh.read(1) != b'\x00' else b'\x01' * 64)
    with B.BagReader(path) as r:
        got = [t for _, _, t, _ in r.messages(['/camera/image_raw'])]
        notes = r.damage_notes()
    assert got == [2 * 10**9, 3 * 10**9, 5 * 10**9]
    assert sum('2 damaged MCAP chunks skipped' in n for n in notes) == 1, notes
