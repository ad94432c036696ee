"""The MCAP chunks' CRC-32 (csrc/record/crc32.cpp) against zlib's, and the chunks rblog's
writer finalizes itself (mcap_writer._Writer) against mcap's own Writer, byte for byte."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

import rblog
from rblog.engine.runner import TrajectoryCollector
from rblog.record import _encode, mcap_writer

from conftest import SAMPLES_DIR


def test_crc32_is_zlibs():
    """Every length 0..300 (below, at and past the 64-byte folding threshold and its 16-byte
    steps) at unaligned offsets, with three starting CRCs (a CRC continued over more data), and
    a 1 MB buffer (the folding loop proper): the same value as zlib.crc32."""
    rng = np.random.default_rng(7)
    buf = rng.integers(0, 256, 1 << 20, dtype=np.uint8)
    for n in range(301):
        for off in (0, 1, 7, 13):
            data = buf[off:off + n]
            for start in (0, 0xFFFFFFFF, 0x1234ABCD):
                assert _encode.crc32(data, start) == zlib.crc32(data.tobytes(), start), (n, off)
    assert _encode.crc32(buf) == zlib.crc32(buf.tobytes())
    # read-only buffers (a chunk's bytes)
    assert _encode.crc32(np.frombuffer(b"123456789", np.uint8)) == 0xCBF43926  # the check value


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_chunks_are_mcaps_own(tmp_path, monkeypatch, compression):
    """The same blocks written through rblog's chunk finalization and through mcap's own Writer
    (chunks closed only by size: FLUSH_EVERY_S out of reach) give the same file, byte for byte;
    mcap's reader checks every chunk's CRC."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    monkeypatch.setattr(mcap_writer, "FLUSH_EVERY_S", 1e9)
    scene = rblog.load_scene(str(SAMPLES_DIR / "spinning_bodies.toml"))
    col = TrajectoryCollector()
    rblog.run(scene, duration=1.0, recorders=[col])

    def write(path):
        rec = mcap_writer.McapRecorder(str(path), compression=compression)
        rec.open(col.blocks[0].model, col.blocks[0].info)
        for b in col.blocks:
            rec.write(b)
        rec.close()
        return path.read_bytes()

    ours = write(tmp_path / "ours.mcap")
    monkeypatch.setattr(mcap_writer, "_Writer", Writer)
    theirs = write(tmp_path / "theirs.mcap")
    assert len(ours) > 4 << 20  # several 1 MB chunks
    assert ours == theirs
    with open(tmp_path / "ours.mcap", "rb") as f:
        n = sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages())
    assert n == 3 * 101 + 3  # State, Metrics, /tf per sample; run, scene, status
